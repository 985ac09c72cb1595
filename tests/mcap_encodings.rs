//! MCAP logs as users record them: protobuf and ROS 2 (CDR) messages, checked against
//! files and values written by the official MCAP libraries (tests/data/mcap/make_encodings.py),
//! the JSON run of the bundled archive, prost-reflect's full decode, and hostile payloads.

mod common;

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use proptest::prelude::*;
use prost_reflect::prost::Message as _;
use prost_reflect::{DynamicMessage, MessageDescriptor, Value};
use railgrip::config::DEFAULT_PIPELINE_TOML;
use railgrip::estimate::estimate;
use railgrip::ingest::MessageDecoder;
use railgrip::{ingest_file, Pipeline};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/mcap")
        .join(name)
}

/// The default pipeline with its `[ingest.mcap]` section replaced by `mapping`.
fn pipeline_with(mapping: &str) -> Pipeline {
    Pipeline::from_toml(&common::pipeline_text_with_mcap(mapping), "test pipeline").unwrap()
}

fn mapping(name: &str) -> String {
    common::mcap_mapping(name)
}

/// (topic, encoding, schema name, schema encoding, schema data, sequence, log time, payload).
type Msg = (String, String, String, String, Vec<u8>, u32, u64, Vec<u8>);

fn messages(path: &Path) -> Vec<Msg> {
    let bytes = std::fs::read(path).unwrap();
    mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            let s = m.channel.schema.as_ref().unwrap();
            (
                m.channel.topic.clone(),
                m.channel.message_encoding.clone(),
                s.name.clone(),
                s.encoding.clone(),
                s.data.to_vec(),
                m.sequence,
                m.log_time,
                m.data.to_vec(),
            )
        })
        .collect()
}

/// Writes `msgs` as an MCAP file (one schema and channel per topic), `edit` applied first.
fn write_mcap(path: &Path, msgs: &[Msg], metadata: Option<BTreeMap<String, String>>) {
    let mut w = mcap::WriteOptions::new()
        .create(std::io::BufWriter::new(
            std::fs::File::create(path).unwrap(),
        ))
        .unwrap();
    let mut channels: BTreeMap<String, u16> = BTreeMap::new();
    if let Some(m) = metadata {
        w.write_metadata(&mcap::records::Metadata {
            name: "run".into(),
            metadata: m,
        })
        .unwrap();
    }
    for (topic, enc, sname, senc, sdata, seq, t, payload) in msgs {
        let id = match channels.get(topic) {
            Some(&id) => id,
            None => {
                let sid = w.add_schema(sname, senc, sdata).unwrap();
                let id = w.add_channel(sid, topic, enc, &BTreeMap::new()).unwrap();
                channels.insert(topic.clone(), id);
                id
            }
        };
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: id,
                sequence: *seq,
                log_time: *t,
                publish_time: *t,
            },
            payload,
        )
        .unwrap();
    }
    w.finish().unwrap();
}

fn soap_metadata(path: &Path) -> BTreeMap<String, String> {
    let bytes = std::fs::read(path).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    let idx = &summary.metadata_indexes[0];
    let rec = mcap::read::metadata(&bytes, idx).unwrap();
    rec.metadata
}

#[test]
fn small_files_read_as_the_official_decoders_read_them() {
    let expected: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(data("small.expected.json")).unwrap())
            .unwrap();
    for (key, file) in [
        ("protobuf", "small.protobuf.mcap"),
        ("ros2", "small.ros2.mcap"),
    ] {
        let paths: Vec<&str> = expected[key]["paths"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| p.as_str().unwrap())
            .collect();
        let msgs = messages(&data(file));
        assert_eq!(msgs.len(), 3);
        for (k, (_, enc, sname, _, sdata, ..)) in msgs.iter().enumerate() {
            let payload = &msgs[k].7;
            // Ten paths at most per decoder: read them in two groups.
            for group in paths.chunks(9) {
                let d = MessageDecoder::new(enc, sname, sdata, group, true).unwrap();
                let got = d.extract(payload, &[]).unwrap();
                for (j, p) in group.iter().enumerate() {
                    let want = expected[key]["messages"][k][p].as_f64().unwrap();
                    assert_eq!(got[j], Some(want), "{file} message {k} {p}");
                }
                // The header stamp slots.
                let (s, n) = match key {
                    "protobuf" => ("header.stamp.seconds", "header.stamp.nanos"),
                    _ => ("header.stamp.sec", "header.stamp.nanosec"),
                };
                let m = &expected[key]["messages"][k];
                assert_eq!(got[group.len()], m[s].as_f64());
                assert_eq!(got[group.len() + 1], m[n].as_f64());
            }
        }
    }
}

fn assert_same_estimates(a: &Path, pa: &Pipeline, b: &Path, pb: &Pipeline) {
    let la = ingest_file(a, pa).unwrap();
    let lb = ingest_file(b, pb).unwrap();
    assert_eq!(la.len(), lb.len(), "{}", b.display());
    assert_eq!(la.start_log_time_ns, lb.start_log_time_ns);
    assert_eq!(la.metadata, lb.metadata);
    let ea = estimate(&la, pa).unwrap();
    let eb = estimate(&lb, pb).unwrap();
    let mut worst = 0.0f64;
    for (x, y) in ea.axles.iter().zip(&eb.axles) {
        assert_eq!(x.valid, y.valid);
        for (u, v) in [
            (&x.mu, &y.mu),
            (&x.dv_mps, &y.dv_mps),
            (&x.ddv_mps2, &y.ddv_mps2),
            (&x.normal_n, &y.normal_n),
        ] {
            for (p, q) in u.iter().zip(v) {
                if p.is_finite() || q.is_finite() {
                    worst = worst.max((p - q).abs());
                }
            }
        }
    }
    for (p, q) in ea.v_mps.iter().zip(&eb.v_mps) {
        worst = worst.max((p - q).abs());
    }
    println!("{}: largest difference from JSON {worst:e}", b.display());
    assert!(worst <= 1e-9, "{}: {worst}", b.display());
}

#[test]
fn protobuf_and_ros2_runs_give_the_json_runs_estimates() {
    let json = common::fixture("soap_160kmh_0c.mcap");
    let default = Pipeline::default_uic_z1();
    for (file, map) in [
        ("soap_160kmh_0c.protobuf.mcap", "protobuf.toml"),
        ("soap_160kmh_0c.ros2.mcap", "ros2.toml"),
    ] {
        let m = mapping(map);
        assert_same_estimates(&json, &default, &data(file), &pipeline_with(&m));
        // The messages' own stamps (equal to the log times in these files) give the same.
        // (std_msgs/Float64 has no header: the pressures keep the log time there.)
        let stamped: String = m
            .lines()
            .map(|l| {
                if l.contains("omega") || l.contains("v_radar") || map == "protobuf.toml" {
                    l.replace("unit = \"", "time = \"header\", unit = \"")
                } else {
                    l.to_string()
                }
            })
            .collect::<Vec<_>>()
            .join("\n");
        assert_same_estimates(&json, &default, &data(file), &pipeline_with(&stamped));
    }
}

/// `msgs` of the ROS 2 soap run with `edit` applied, written to `dir/name`.
fn edited(dir: &Path, name: &str, source: &str, edit: impl Fn(&mut Vec<Msg>)) -> PathBuf {
    let src = data(source);
    let mut msgs = messages(&src);
    edit(&mut msgs);
    let path = dir.join(name);
    write_mcap(&path, &msgs, Some(soap_metadata(&src)));
    path
}

fn err(path: &Path, p: &Pipeline) -> String {
    format!("{}", ingest_file(path, p).unwrap_err())
}

#[allow(clippy::too_many_lines)] // a test or benchmark: one scenario end to end
#[test]
fn bad_encodings_schemas_messages_and_paths_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let ros2 = pipeline_with(&mapping("ros2.toml"));
    let pb = pipeline_with(&mapping("protobuf.toml"));

    // A message cut short: topic, sequence and byte offset named.
    let p = edited(dir.path(), "cut.mcap", "soap_160kmh_0c.ros2.mcap", |m| {
        let k = m
            .iter()
            .filter(|x| x.0 == "/joint_states")
            .nth(100)
            .map(|x| x.5)
            .unwrap();
        let msg = m
            .iter_mut()
            .find(|x| x.0 == "/joint_states" && x.5 == k)
            .unwrap();
        msg.7.truncate(60);
    });
    let e = err(&p, &ros2);
    assert!(e.contains("topic /joint_states, message #100"), "{e}");
    assert!(
        e.contains("sequence 100: the CDR message does not decode against its schema"),
        "{e}"
    );
    assert!(e.contains("but the message ends at byte 60"), "{e}");

    // A CDR string longer than the message.
    let p = edited(dir.path(), "long.mcap", "soap_160kmh_0c.ros2.mcap", |m| {
        let msg = m.iter_mut().find(|x| x.0 == "/radar/twist").unwrap();
        msg.7[12..16].copy_from_slice(&1_000_000u32.to_le_bytes());
    });
    let e = err(&p, &ros2);
    assert!(e.contains("needs 1000000 byte(s) at byte 16"), "{e}");

    // A protobuf payload with a length running past its end.
    let p = edited(dir.path(), "pb.mcap", "soap_160kmh_0c.protobuf.mcap", |m| {
        let msg = m.iter_mut().find(|x| x.0 == "/tachometers").unwrap();
        let n = msg.7.len();
        msg.7.truncate(n - 3);
    });
    let e = err(&p, &pb);
    assert!(
        e.contains("sequence 0: the protobuf message does not decode"),
        "{e}"
    );
    assert!(e.contains("at byte"), "{e}");

    // Unknown encoding: the supported ones named.
    let p = edited(dir.path(), "enc.mcap", "soap_160kmh_0c.ros2.mcap", |m| {
        for x in m.iter_mut().filter(|x| x.0 == "/radar/twist") {
            x.1 = "flatbuffer".into();
        }
    });
    let e = err(&p, &ros2);
    assert!(e.contains("message encoding \"flatbuffer\""), "{e}");
    assert!(
        e.contains("\"json\", \"protobuf\" (protobuf schema) and \"cdr\" (ros2msg schema)"),
        "{e}"
    );

    // A schema that does not parse.
    let p = edited(
        dir.path(),
        "schema.mcap",
        "soap_160kmh_0c.protobuf.mcap",
        |m| {
            for x in m.iter_mut().filter(|x| x.0 == "/radar/speed") {
                x.4 = b"\x0a\xff\xff not a descriptor set".to_vec();
            }
        },
    );
    let e = err(&p, &pb);
    assert!(
        e.contains(
            "topic /radar/speed: protobuf schema railgrip.test.RadarSpeed: the protobuf schema"
        ),
        "{e}"
    );
    assert!(e.contains("is not a valid FileDescriptorSet"), "{e}");
    let p = edited(dir.path(), "idl.mcap", "soap_160kmh_0c.ros2.mcap", |m| {
        for x in m.iter_mut().filter(|x| x.0 == "/radar/twist") {
            x.3 = "ros2idl".into();
        }
    });
    let e = err(&p, &ros2);
    assert!(
        e.contains("railgrip reads \"cdr\" messages with \"ros2msg\" schemas"),
        "{e}"
    );
    assert!(e.contains("rosbag2 writes by default"), "{e}");
    let p = edited(dir.path(), "msgdef.mcap", "soap_160kmh_0c.ros2.mcap", |m| {
        for x in m.iter_mut().filter(|x| x.0 == "/radar/twist") {
            x.4 = b"std_msgs/Header header\ngeometry_msgs/Twist twist\n".to_vec();
        }
    });
    let e = err(&p, &ros2);
    assert!(e.contains("no definition of std_msgs/Header"), "{e}");

    // A field path that is not in the schema: the fields that are, listed.
    let bad = pipeline_with(&mapping("ros2.toml").replace("twist.linear.x", "twist.linear.v"));
    let e = err(&data("soap_160kmh_0c.ros2.mcap"), &bad);
    assert!(e.contains("topic /radar/twist: ros2msg schema geometry_msgs/msg/TwistStamped: geometry_msgs/Vector3 has no field \"v\"; its fields: float64 x, float64 y, float64 z"), "{e}");
    let bad = pipeline_with(&mapping("protobuf.toml").replace("omega[0]", "omegas[0]"));
    let e = err(&data("soap_160kmh_0c.protobuf.mcap"), &bad);
    assert!(e.contains("railgrip.test.Tachometers has no field \"omegas\"; its fields: google.protobuf.Timestamp timestamp, repeated string name, repeated double omega"), "{e}");
    // Unsupported field types, named.
    let bad = pipeline_with(&mapping("protobuf.toml").replace("twist.linear.x", "frame_id"));
    let e = err(&data("soap_160kmh_0c.protobuf.mcap"), &bad);
    assert!(
        e.contains("frame_id is a string, not a number (unsupported field type"),
        "{e}"
    );
    let bad = pipeline_with(&mapping("ros2.toml").replace("velocity[0]", "name[0]"));
    let e = err(&data("soap_160kmh_0c.ros2.mcap"), &bad);
    assert!(
        e.contains("is a string[], not a number (unsupported field type"),
        "{e}"
    );
    // An element beyond the array.
    let bad = pipeline_with(&mapping("ros2.toml").replace("velocity[3]", "velocity[4]"));
    let e = err(&data("soap_160kmh_0c.ros2.mcap"), &bad);
    assert!(
        e.contains("velocity has 4 element(s); [4] is out of range"),
        "{e}"
    );
    // time = "header" on a message without a header.
    let bad = pipeline_with(&mapping("ros2.toml").replace(
        "field = \"data\", unit",
        "field = \"data\", time = \"header\", unit",
    ));
    let e = err(&data("soap_160kmh_0c.ros2.mcap"), &bad);
    assert!(e.contains("time = \"header\" needs a std_msgs/Header field `header`: std_msgs/Float64 has no field \"header\""), "{e}");
    // time = "header" on a JSON channel.
    let default = DEFAULT_PIPELINE_TOML.replace(
        "field = \"v\", unit",
        "field = \"v\", time = \"header\", unit",
    );
    let p = Pipeline::from_toml(&default, "t").unwrap();
    let e = err(&common::fixture("soap_160kmh_0c.mcap"), &p);
    assert!(
        e.contains("time = \"header\" is set, but the channel is JSON"),
        "{e}"
    );
    // Signals on one topic share its clock.
    let e = Pipeline::from_toml(
        &common::pipeline_text_with_mcap(&mapping("ros2.toml").replacen(
            "field = \"velocity[0]\", unit",
            "field = \"velocity[0]\", time = \"header\", unit",
            1,
        )),
        "t.toml",
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("ingest.mcap.omega2.time = \"log\": omega1 on the same topic /joint_states has time = \"header\""),
        "{e}"
    );
    // A bad `time` value is a pipeline error.
    let e = Pipeline::from_toml(
        &DEFAULT_PIPELINE_TOML
            .replace("field = \"v\", unit", "field = \"v\", time = \"gps\", unit"),
        "t.toml",
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("ingest.mcap.v_radar.time = \"gps\": use \"log\""),
        "{e}"
    );
}

/// The Corner message type of small.protobuf.mcap.
fn corner() -> (Vec<u8>, MessageDescriptor) {
    let msgs = messages(&data("small.protobuf.mcap"));
    let pool = prost_reflect::DescriptorPool::decode(msgs[0].4.as_slice()).unwrap();
    (
        msgs[0].4.clone(),
        pool.get_message_by_name("railgrip.test.Corner").unwrap(),
    )
}

/// The value at `path` of a decoded message, as prost-reflect reads it.
fn dynamic_value(m: &DynamicMessage, path: &str) -> Option<f64> {
    let mut cur: Cow<DynamicMessage> = Cow::Borrowed(m);
    let parts: Vec<&str> = path.split('.').collect();
    for (k, part) in parts.iter().enumerate() {
        let (name, idx) = match part.find('[') {
            Some(o) => (
                &part[..o],
                Some(part[o + 1..part.len() - 1].parse::<usize>().unwrap()),
            ),
            None => (*part, None),
        };
        let v = cur.get_field_by_name(name)?.into_owned();
        let v = match idx {
            Some(i) => match v {
                Value::List(l) => l.get(i)?.clone(),
                _ => return None,
            },
            None => v,
        };
        let last = k + 1 == parts.len();
        match v {
            Value::Message(sub) if !last => cur = Cow::Owned(sub),
            Value::Message(sub) => return dynamic_value(&sub, "value"),
            Value::F64(x) => return Some(x),
            Value::F32(x) => return Some(x as f64),
            Value::I32(x) | Value::EnumNumber(x) => return Some(x as f64),
            Value::I64(x) => return Some(x as f64),
            Value::U32(x) => return Some(x as f64),
            Value::U64(x) => return Some(x as f64),
            Value::Bool(b) => return Some(b as u8 as f64),
            _ => return None,
        }
    }
    None
}

const CORNER_PATHS: [&str; 9] = [
    "samples[1].value",
    "unpacked[2]",
    "packed[0]",
    "wrapped",
    "zigzag",
    "negative",
    "sfixed",
    "mode",
    "twist.angular.z",
];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// railgrip's wire walk reads what prost-reflect's full decode reads, on random messages.
    #[test]
    fn protobuf_walk_agrees_with_prost_reflect(
        samples in proptest::collection::vec(-1e3f32..1e3, 2..5),
        unpacked in proptest::collection::vec(any::<i32>(), 3..6),
        packed in proptest::collection::vec(any::<u64>(), 1..4),
        wrapped in any::<i64>(),
        zigzag in any::<i64>(),
        negative in any::<i32>(),
        sfixed in any::<i32>(),
        mode in prop_oneof![Just(0), Just(7)],
        z in -1e6f64..1e6,
        twice in any::<bool>(),
    ) {
        let (schema, desc) = corner();
        let mut m = DynamicMessage::new(desc.clone());
        let sample = desc.get_field_by_name("samples").unwrap();
        let sample_desc = match sample.kind() { prost_reflect::Kind::Message(d) => d, _ => unreachable!() };
        m.set_field_by_name("samples", Value::List(samples.iter().map(|v| {
            let mut s = DynamicMessage::new(sample_desc.clone());
            s.set_field_by_name("value", Value::F32(*v));
            Value::Message(s)
        }).collect()));
        m.set_field_by_name("unpacked", Value::List(unpacked.iter().map(|x| Value::I32(*x)).collect()));
        m.set_field_by_name("packed", Value::List(packed.iter().map(|x| Value::U64(*x)).collect()));
        let wdesc = match desc.get_field_by_name("wrapped").unwrap().kind() { prost_reflect::Kind::Message(d) => d, _ => unreachable!() };
        let mut w = DynamicMessage::new(wdesc);
        w.set_field_by_name("value", Value::I64(wrapped));
        m.set_field_by_name("wrapped", Value::Message(w));
        m.set_field_by_name("zigzag", Value::I64(zigzag));
        m.set_field_by_name("negative", Value::I32(negative));
        m.set_field_by_name("sfixed", Value::I32(sfixed));
        m.set_field_by_name("mode", Value::EnumNumber(mode));
        let tdesc = match desc.get_field_by_name("twist").unwrap().kind() { prost_reflect::Kind::Message(d) => d, _ => unreachable!() };
        let vdesc = match tdesc.get_field_by_name("angular").unwrap().kind() { prost_reflect::Kind::Message(d) => d, _ => unreachable!() };
        let mut v = DynamicMessage::new(vdesc);
        v.set_field_by_name("z", Value::F64(z));
        let mut t = DynamicMessage::new(tdesc);
        t.set_field_by_name("angular", Value::Message(v));
        m.set_field_by_name("twist", Value::Message(t));
        let mut bytes = m.encode_to_vec();
        if twice {
            // A message sent twice is merged: later scalars win, lists grow.
            bytes.extend(m.encode_to_vec());
        }
        let reference = DynamicMessage::decode(desc, bytes.as_slice()).unwrap();
        let d = MessageDecoder::new("protobuf", "railgrip.test.Corner", &schema, &CORNER_PATHS, false).unwrap();
        let got = d.extract(&bytes, &[]).unwrap();
        for (k, p) in CORNER_PATHS.iter().enumerate() {
            prop_assert_eq!(got[k], dynamic_value(&reference, p), "{}", p);
        }
    }

    /// Mutated protobuf and CDR payloads give values or errors, never a panic.
    #[test]
    fn mutated_payloads_never_panic(
        which in 0usize..6,
        edits in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..6),
        cut in any::<usize>(),
        grow in proptest::collection::vec(any::<u8>(), 0..16),
    ) {
        let expected: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(data("small.expected.json")).unwrap(),
        ).unwrap();
        let (file, key) = if which < 3 { ("small.protobuf.mcap", "protobuf") } else { ("small.ros2.mcap", "ros2") };
        let msgs = messages(&data(file));
        let (_, enc, sname, _, sdata, _, _, payload) = &msgs[which % 3];
        let paths: Vec<&str> = expected[key]["paths"].as_array().unwrap().iter().take(9).map(|p| p.as_str().unwrap()).collect();
        let d = MessageDecoder::new(enc, sname, sdata, &paths, true).unwrap();
        let mut p = payload.clone();
        for (at, b) in &edits {
            let n = p.len();
            if n > 0 { p[at % n] = *b; }
        }
        p.truncate(cut % (p.len() + 1));
        p.extend(&grow);
        if let Ok(v) = d.extract(&p, &[]) {
            prop_assert_eq!(v.len(), paths.len() + 2);
        }
        let _ = d.decode_whole(&p);
    }

    /// Mutated schemas (descriptor sets, message definitions) give a decoder or an error.
    #[test]
    fn mutated_schemas_never_panic(
        which in 0usize..2,
        edits in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..8),
        cut in any::<usize>(),
    ) {
        let (file, paths): (&str, &[&str]) = if which == 0 {
            ("small.protobuf.mcap", &["twist.angular.z", "samples[1].value"])
        } else {
            ("small.ros2.mcap", &["points[1].x", "value"])
        };
        let msgs = messages(&data(file));
        let (_, enc, sname, _, sdata, _, _, payload) = &msgs[0];
        let mut schema = sdata.clone();
        for (at, b) in &edits {
            let n = schema.len();
            schema[at % n] = *b;
        }
        schema.truncate(cut % (schema.len() + 1));
        if let Ok(d) = MessageDecoder::new(enc, sname, &schema, paths, true) {
            let _ = d.extract(payload, &[]);
            let _ = d.decode_whole(payload);
        }
    }
}

#[test]
fn committed_runs_hold_the_json_runs_messages_on_every_mapped_topic() {
    for (file, topics) in [
        (
            "soap_160kmh_0c.protobuf.mcap",
            ["/radar/speed", "/tachometers", "/axle1/pressure"],
        ),
        (
            "soap_160kmh_0c.ros2.mcap",
            ["/radar/twist", "/joint_states", "/axle4/pressure"],
        ),
    ] {
        let msgs = messages(&data(file));
        for t in topics {
            assert_eq!(
                msgs.iter().filter(|m| m.0 == t).count(),
                24_259,
                "{file} {t}"
            );
        }
    }
}

/// The official MCAP reader (CI installs it; skipped with a message elsewhere).
fn official_reader_available() -> bool {
    common::python_has("mcap.reader", "mcap")
}

#[test]
fn estimate_writes_a_replay_mcap_that_the_official_reader_reads_back() {
    if !official_reader_available() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let log = common::fixture("soap_160kmh_0c.mcap");
    let model_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/golden/synthetic_mlp.json");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_railgrip"))
        .args(["estimate", log.to_str().unwrap(), "--out"])
        .arg(dir.path())
        .args(["--mcap", "--model", model_path.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let replay = dir.path().join("soap_160kmh_0c.railgrip.mcap");
    assert!(String::from_utf8_lossy(&out.stdout).contains("soap_160kmh_0c.railgrip.mcap"));
    let read = std::process::Command::new("python3")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mcap/read_replay.py"))
        .arg(&replay)
        .output()
        .unwrap();
    assert!(
        read.status.success(),
        "{}",
        String::from_utf8_lossy(&read.stderr)
    );
    let got: serde_json::Value = serde_json::from_slice(&read.stdout).unwrap();

    // The same run estimated here, and the input's log times.
    let p = Pipeline::default_uic_z1();
    let runlog = ingest_file(&log, &p).unwrap();
    let e = estimate(&runlog, &p).unwrap();
    let model = railgrip::model::Model::load(&model_path).unwrap();
    let t0 = runlog.start_log_time_ns.unwrap();
    let n = e.len();
    let topics = got["topics"].as_object().unwrap();
    assert_eq!(
        topics.len(),
        1 + 4 * 7,
        "{:?}",
        topics.keys().collect::<Vec<_>>()
    );
    assert_eq!(got["message_count"].as_u64().unwrap() as usize, 29 * n);
    let input_times: Vec<u64> = messages(&log)
        .iter()
        .filter(|m| m.0 == "/radar/speed")
        .map(|m| m.6)
        .collect();
    let speed = &topics["/railgrip/v_mps"];
    assert_eq!(speed["schema_encoding"], "jsonschema");
    assert_eq!(speed["message_encoding"], "json");
    assert_eq!(speed["schema"]["required"][0], "v_mps");
    let times: Vec<u64> = speed["log_times"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t.as_u64().unwrap())
        .collect();
    assert_eq!(times.len(), n);
    assert_eq!(times[0], t0);
    assert_eq!(times[0], input_times[0]);
    // The uniform time base at 417 Hz: every sample on the input's clock within half a period.
    assert!(times
        .iter()
        .zip(&e.time_s)
        .all(|(&t, s)| t == t0 + (s * 1e9).round() as u64));
    let as_f64 = |v: &serde_json::Value| v.as_f64().unwrap_or(f64::NAN);
    let same = |a: f64, b: f64| (a.is_nan() && b.is_nan()) || a == b;
    for a in 0..4 {
        let ax = &e.axles[a];
        let topic = |f: &str| &topics[&format!("/railgrip/axle{}/{f}", a + 1)]["values"];
        for (f, want) in [
            ("dv_mps", &ax.dv_mps),
            ("ddv_mps2", &ax.ddv_mps2),
            ("normal_N", &ax.normal_n),
            ("tangential_N", &ax.tangential_n),
            ("mu", &ax.mu),
        ] {
            let vals = topic(f).as_array().unwrap();
            assert_eq!(vals.len(), n);
            for (i, v) in vals.iter().enumerate() {
                assert!(
                    same(as_f64(v), want[i]) || (v.is_null() && !want[i].is_finite()),
                    "{f} axle {} sample {i}",
                    a + 1
                );
            }
        }
        let valid = topic("valid").as_array().unwrap();
        assert!(valid
            .iter()
            .zip(&ax.valid)
            .all(|(v, w)| v.as_bool() == Some(*w)));
        let mm = topic("mu_model").as_array().unwrap();
        let t_c = e.metadata.ambient_temperature_c.unwrap_or(f64::NAN);
        let mut checked = 0;
        for (i, v) in mm.iter().enumerate() {
            if ax.dv_mps[i].is_finite() && ax.ddv_mps2[i].is_finite() {
                assert_eq!(
                    as_f64(v),
                    model.mu_vt(ax.dv_mps[i], ax.ddv_mps2[i], e.v_mps[i], t_c)
                );
                checked += 1;
            } else {
                assert!(v.is_null());
            }
        }
        assert!(checked > n / 2);
    }
}

#[test]
fn estimate_refuses_a_bad_replay_model_before_estimating_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let log = common::fixture("soap_160kmh_0c.mcap");
    let bad = dir.path().join("model.json");
    std::fs::write(&bad, "{\"format\": \"not a model\"}").unwrap();
    let out_dir = dir.path().join("out");
    let go = |extra: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_railgrip"))
            .args([
                "estimate",
                log.to_str().unwrap(),
                "--out",
                out_dir.to_str().unwrap(),
            ])
            .args(extra)
            .output()
            .unwrap()
    };
    let o = go(&["--mcap", "--model", bad.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("model.json"), "{e}");
    assert!(!out_dir.exists(), "nothing written");
    // --model without --mcap is a usage error.
    let o = go(&["--model", bad.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--mcap"));
}

#[test]
fn run_writes_replays_per_run_and_removes_them_when_not_asked() {
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("campaign");
    common::two_run_campaign(&camp);
    let out = dir.path().join("out");
    let run = |extra: &[&str]| {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_railgrip"))
            .args([
                "run",
                camp.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ])
            .args(extra)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    run(&["--mcap"]);
    let names = ["soap_120kmh_p20", "soap_120kmh_m20"];
    for name in names {
        let path = out
            .join("runs")
            .join(name)
            .join(format!("{name}.railgrip.mcap"));
        let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
        let topics: std::collections::BTreeSet<&str> = summary
            .channels
            .values()
            .map(|c| c.topic.as_str())
            .collect();
        assert!(topics.contains("/railgrip/axle2/mu_model"), "{topics:?}");
        assert!(topics.contains("/railgrip/axle4/valid"));
        // CSV logs: the time base is the log's time column.
        let first = mcap::MessageStream::new(&bytes)
            .unwrap()
            .next()
            .unwrap()
            .unwrap();
        assert!(first.log_time < 1_000_000_000, "{}", first.log_time);
    }
    run(&[]);
    for name in names {
        assert!(!out
            .join("runs")
            .join(name)
            .join(format!("{name}.railgrip.mcap"))
            .exists());
    }
}
