//! Campaigns and outputs in object storage (`s3://`), against a real S3 API server: moto's
//! server mode (PyPI `moto[server]`) on 127.0.0.1, one per test. Without moto the tests are
//! skipped with a message, except under CI=true (`.ci/run` installs it).

mod common;

use std::collections::BTreeMap;
use std::net::TcpListener;
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use common::{fixture, python_has};

/// A moto S3 server on a free port, stopped on drop.
struct Moto {
    child: Child,
    endpoint: String,
}

impl Drop for Moto {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

impl Moto {
    fn start() -> Option<Moto> {
        if !python_has("moto.server", "'moto[server]>=5.2,<5.3'") {
            return None;
        }
        let port = free_port();
        let child = Command::new("python3")
            .args([
                "-m",
                "moto.server",
                "-H",
                "127.0.0.1",
                "-p",
                &port.to_string(),
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("python3 -m moto.server starts");
        let moto = Moto {
            child,
            endpoint: format!("http://127.0.0.1:{port}"),
        };
        let t = Instant::now();
        while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
            assert!(t.elapsed() < Duration::from_secs(30), "moto did not start");
            std::thread::sleep(Duration::from_millis(100));
        }
        Some(moto)
    }

    /// Runs boto3 code with `s3` bound to a client of this server.
    fn python(&self, code: &str) -> String {
        let o = Command::new("python3")
            .arg("-c")
            .arg(format!(
                "import boto3, sys\ns3 = boto3.client('s3', endpoint_url='{}', region_name='us-east-1', aws_access_key_id='test', aws_secret_access_key='test')\n{code}",
                self.endpoint
            ))
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).into_owned()
    }

    fn make_bucket(&self, bucket: &str) {
        self.python(&format!("s3.create_bucket(Bucket='{bucket}')"));
    }

    fn upload(&self, bucket: &str, key: &str, file: &Path) {
        self.python(&format!(
            "s3.upload_file({:?}, '{bucket}', '{key}')",
            file.display().to_string()
        ));
    }

    fn put_bytes(&self, bucket: &str, key: &str, bytes: &[u8]) {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("object");
        std::fs::write(&f, bytes).unwrap();
        self.upload(bucket, key, &f);
    }

    /// Every object below `prefix/` (relative key → bytes).
    fn download(&self, bucket: &str, prefix: &str) -> BTreeMap<String, Vec<u8>> {
        let dir = tempfile::tempdir().unwrap();
        self.python(&format!(
            "import os\np = s3.get_paginator('list_objects_v2')\nfor page in p.paginate(Bucket='{bucket}', Prefix='{prefix}/'):\n    for o in page.get('Contents', []):\n        rel = o['Key'][len('{prefix}/'):]\n        dest = os.path.join({:?}, rel)\n        os.makedirs(os.path.dirname(dest), exist_ok=True)\n        s3.download_file('{bucket}', o['Key'], dest)",
            dir.path().display().to_string()
        ));
        files_below(dir.path())
    }

    /// `railgrip ARGS` with this server as the AWS endpoint.
    fn railgrip(&self, args: &[&str], cwd: &Path) -> Output {
        Command::new(env!("CARGO_BIN_EXE_railgrip"))
            .args(args)
            .current_dir(cwd)
            .env("AWS_ACCESS_KEY_ID", "test")
            .env("AWS_SECRET_ACCESS_KEY", "test")
            .env("AWS_REGION", "us-east-1")
            .env("AWS_ENDPOINT_URL", &self.endpoint)
            .env("AWS_ALLOW_HTTP", "true")
            // Model files carry the time they were made: the same time for byte comparisons.
            .env("SOURCE_DATE_EPOCH", "1763692800")
            .output()
            .unwrap()
    }
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// Every file below `dir` but `timings.json` (relative path → bytes).
fn files_below(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.file_name().unwrap() != "timings.json" {
                let rel = p.strip_prefix(dir).unwrap().to_string_lossy().into_owned();
                out.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    out
}

const RUNS: [&str; 5] = [
    "soap_120kmh_p20.csv",
    "soap_120kmh_p20.meta.toml",
    "soap_120kmh_m20.csv",
    "soap_120kmh_m20.meta.toml",
    "soap_160kmh_0c.mcap",
];

fn upload_campaign(moto: &Moto, bucket: &str, prefix: &str) {
    moto.make_bucket(bucket);
    for f in RUNS {
        moto.upload(bucket, &format!("{prefix}/{f}"), &fixture(f));
    }
}

fn assert_same(a: &BTreeMap<String, Vec<u8>>, b: &BTreeMap<String, Vec<u8>>, what: &str) {
    assert_eq!(
        a.keys().collect::<Vec<_>>(),
        b.keys().collect::<Vec<_>>(),
        "{what}"
    );
    for (k, v) in a {
        assert!(b[k] == *v, "{k} differs: {what}");
    }
}

#[test]
fn a_campaign_in_a_bucket_runs_into_a_bucket_with_the_bytes_of_a_local_output() {
    let Some(moto) = Moto::start() else { return };
    let dir = tempfile::tempdir().unwrap();
    upload_campaign(&moto, "camp", "2026/a");
    // Someone else's object below the output prefix: railgrip never removes it.
    moto.put_bytes("camp", "2026/out/notes/keep.txt", b"mine");
    let o = moto.railgrip(
        &["run", "s3://camp/2026/a", "--out", "s3://camp/2026/out"],
        dir.path(),
    );
    let out = text(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{out}{}", text(&o.stderr));
    assert!(
        out.contains("report     s3://camp/2026/out/report/index.html"),
        "{out}"
    );
    let local = moto.railgrip(&["run", "s3://camp/2026/a", "--out", "local"], dir.path());
    assert_eq!(local.status.code(), Some(0), "{}", text(&local.stderr));
    let mut remote = moto.download("camp", "2026/out");
    assert_eq!(
        remote.remove("notes/keep.txt").as_deref(),
        Some(&b"mine"[..])
    );
    let here = files_below(&dir.path().join("local"));
    assert!(here.contains_key("campaign.json") && here.len() >= 12);
    assert_same(&here, &remote, "the bucket's output against the local one");
    // The logs' provenance names them by their URIs.
    let campaign = String::from_utf8(remote["campaign.json"].clone()).unwrap();
    assert!(
        campaign.contains("\"source\": \"s3://camp/2026/a/soap_160kmh_0c.mcap\""),
        "{campaign}"
    );
    // A second run reuses every run from the bucket and writes the same bytes.
    let again = moto.railgrip(
        &["run", "s3://camp/2026/a", "--out", "s3://camp/2026/out"],
        dir.path(),
    );
    let stderr = text(&again.stderr);
    assert_eq!(again.status.code(), Some(0), "{stderr}");
    assert_eq!(stderr.matches("unchanged, reused").count(), 3, "{stderr}");
    let mut again_remote = moto.download("camp", "2026/out");
    again_remote.remove("notes/keep.txt");
    assert_same(&remote, &again_remote, "a reused re-run");
    // Replay MCAPs written with --mcap are removed by a run without it, like local ones.
    let out_uri = "s3://camp/2026/out";
    let o = moto.railgrip(
        &["run", "s3://camp/2026/a", "--out", out_uri, "--mcap"],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let with = moto.download("camp", "2026/out");
    assert_eq!(
        with.keys()
            .filter(|k| k.ends_with(".railgrip.mcap"))
            .count(),
        3
    );
    let o = moto.railgrip(&["run", "s3://camp/2026/a", "--out", out_uri], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let mut without = moto.download("camp", "2026/out");
    assert!(without.remove("notes/keep.txt").is_some());
    assert_same(&remote, &without, "after a run with --mcap and one without");
    // In parts: the calibration, two shards and the models stage on the bucket give the same
    // bytes (each part takes the calibration.json the first wrote).
    let c = moto.railgrip(
        &[
            "run",
            "s3://camp/2026/a",
            "--out",
            "s3://camp/2026/sharded",
            "--stage",
            "calibrate",
        ],
        dir.path(),
    );
    assert_eq!(c.status.code(), Some(0), "{}", text(&c.stderr));
    assert!(moto
        .download("camp", "2026/sharded")
        .contains_key("calibration.json"));
    for k in ["1/2", "2/2"] {
        let o = moto.railgrip(
            &[
                "run",
                "s3://camp/2026/a",
                "--out",
                "s3://camp/2026/sharded",
                "--stage",
                "estimate",
                "--shard",
                k,
            ],
            dir.path(),
        );
        assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    }
    let m = moto.railgrip(
        &[
            "run",
            "s3://camp/2026/a",
            "--out",
            "s3://camp/2026/sharded",
            "--stage",
            "models",
        ],
        dir.path(),
    );
    assert_eq!(m.status.code(), Some(0), "{}", text(&m.stderr));
    assert_same(
        &remote,
        &moto.download("camp", "2026/sharded"),
        "shards and models in a bucket",
    );
}

#[test]
fn an_archive_object_and_local_files_by_uri_are_campaigns_too() {
    let Some(moto) = Moto::start() else { return };
    let dir = tempfile::tempdir().unwrap();
    moto.make_bucket("arch");
    let tar_path = dir.path().join("c.tar");
    let mut tar = tar::Builder::new(std::fs::File::create(&tar_path).unwrap());
    for f in &RUNS[..4] {
        tar.append_path_with_name(fixture(f), format!("day1/{f}"))
            .unwrap();
    }
    tar.finish().unwrap();
    drop(tar);
    moto.upload("arch", "2026/c.tar", &tar_path);
    let o = moto.railgrip(
        &["run", "s3://arch/2026/c.tar", "--out", "out", "--json"],
        dir.path(),
    );
    let json = text(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    assert!(
        json.contains("\"source\": \"s3://arch/2026/c.tar/day1/soap_120kmh_m20.csv\""),
        "{json}"
    );
    assert!(
        json.contains("\"run\": \"day1__soap_120kmh_m20\""),
        "{json}"
    );
    // file:// names a local folder.
    let camp = dir.path().join("camp");
    common::two_run_campaign(&camp);
    let uri = format!("file://{}", camp.display());
    let o = moto.railgrip(&["run", &uri, "--out", "file_out"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    assert!(dir.path().join("file_out/campaign.json").exists());
}

#[test]
fn bucket_errors_name_the_uri_and_a_damaged_object_fails_its_run_alone() {
    let Some(moto) = Moto::start() else { return };
    let dir = tempfile::tempdir().unwrap();
    upload_campaign(&moto, "camp", "a");
    // A log cut short in the bucket: its run fails, the others train.
    let csv = std::fs::read(fixture("soap_120kmh_p20.csv")).unwrap();
    moto.put_bytes("camp", "a/cut.csv", &csv[..csv.len() / 3 + 17]);
    moto.upload(
        "camp",
        "a/cut.meta.toml",
        &fixture("soap_120kmh_p20.meta.toml"),
    );
    let o = moto.railgrip(
        &["run", "s3://camp/a", "--out", "s3://camp/out"],
        dir.path(),
    );
    let out = text(&o.stdout);
    assert_eq!(o.status.code(), Some(3), "{out}{}", text(&o.stderr));
    assert!(out.contains("failed     cut: s3://camp/a/cut.csv"), "{out}");
    let cases: [(&[&str], &str); 4] = [
        (
            &["run", "s3://nobucket/a", "--out", "o1"],
            "s3://nobucket/a",
        ),
        (
            &["run", "s3://camp/nothing-here", "--out", "o2"],
            "s3://camp/nothing-here: no objects below this prefix",
        ),
        (
            &["run", "s3://camp/a", "--out", "s3://nobucket/out"],
            "s3://nobucket",
        ),
        (
            &["run", "gs://camp/a", "--out", "o3"],
            "gs://camp/a: railgrip does not read gs:// locations",
        ),
    ];
    for (args, expect) in cases {
        let o = moto.railgrip(args, dir.path());
        let err = text(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains(expect) && err.contains("Hint:"),
            "{args:?}: {err}"
        );
    }
    // Nothing listens: a clear error within seconds, not a hang.
    let dead = format!("http://127.0.0.1:{}", free_port());
    let t = Instant::now();
    let o = Command::new(env!("CARGO_BIN_EXE_railgrip"))
        .args(["run", "s3://camp/a", "--out", "o4"])
        .current_dir(dir.path())
        .env("AWS_ACCESS_KEY_ID", "test")
        .env("AWS_SECRET_ACCESS_KEY", "test")
        .env("AWS_REGION", "us-east-1")
        .env("AWS_ENDPOINT_URL", &dead)
        .env("AWS_ALLOW_HTTP", "true")
        .output()
        .unwrap();
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("s3://camp/a") && err.contains("AWS_ENDPOINT_URL"),
        "{err}"
    );
    assert!(t.elapsed() < Duration::from_secs(60), "{:?}", t.elapsed());
    assert!(!dir.path().join("o4/campaign.json").exists());
}

#[test]
fn single_logs_in_a_bucket_are_estimated_and_trained_on_by_uri() {
    let Some(moto) = Moto::start() else { return };
    let dir = tempfile::tempdir().unwrap();
    upload_campaign(&moto, "logs", "r");
    let o = moto.railgrip(
        &[
            "estimate",
            "s3://logs/r/soap_120kmh_p20.csv",
            "--out",
            "remote",
            "--csv",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let here = fixture("soap_120kmh_p20.csv");
    let o = moto.railgrip(
        &[
            "estimate",
            here.to_str().unwrap(),
            "--out",
            "local",
            "--csv",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let table = "soap_120kmh_p20.estimates.csv";
    assert!(
        std::fs::read(dir.path().join("remote").join(table)).unwrap()
            == std::fs::read(dir.path().join("local").join(table)).unwrap(),
        "the estimates of the bucket's log (and its sidecar) differ from the local file's"
    );
    // `train` takes a log and a campaign prefix by URI.
    let o = moto.railgrip(
        &[
            "train",
            "s3://logs/r/soap_160kmh_0c.mcap",
            "s3://logs/r",
            "--out",
            "m",
            "--quiet",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let mlp = std::fs::read_to_string(dir.path().join("m/mlp.json")).unwrap();
    assert!(
        mlp.contains("s3://logs/r/soap_120kmh_m20.csv"),
        "provenance names the URIs"
    );
    let o = moto.railgrip(&["ingest", "s3://logs/r/missing.csv"], dir.path());
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("s3://logs/r/missing.csv: no such object"),
        "{err}"
    );
}

#[test]
fn estimate_ingest_and_train_write_their_files_into_a_bucket() {
    let Some(moto) = Moto::start() else { return };
    let dir = tempfile::tempdir().unwrap();
    upload_campaign(&moto, "logs", "r");
    moto.make_bucket("out");
    let log = fixture("soap_120kmh_p20.csv");
    let log = log.to_str().unwrap();
    for (args, prefix) in [
        (vec!["estimate", log, "--csv", "--mcap"], "e"),
        (vec!["ingest", log], "i"),
        (vec!["train", "s3://logs/r", "--quiet"], "m"),
    ] {
        let remote = format!("s3://out/{prefix}");
        let local = format!("local-{prefix}");
        let mut to_bucket = args.clone();
        to_bucket.extend(["--out", remote.as_str()]);
        let o = moto.railgrip(&to_bucket, dir.path());
        let out = text(&o.stdout);
        assert!(
            matches!(o.status.code(), Some(0) | Some(3)),
            "{}",
            text(&o.stderr)
        );
        assert!(out.contains(&format!("wrote      {remote}/")), "{out}");
        let mut here = args.clone();
        here.extend(["--out", local.as_str()]);
        let o = moto.railgrip(&here, dir.path());
        assert!(matches!(o.status.code(), Some(0) | Some(3)));
        let got = moto.download("out", prefix);
        let want = files_below(&dir.path().join(&local));
        assert!(want.len() >= 2 || prefix == "i", "{:?}", want.keys());
        assert_same(&got, &want, args[0]);
    }
    // A missing output bucket is found before the work, named by its URI.
    let o = moto.railgrip(
        &["estimate", log, "--out", "s3://no-such-bucket/e"],
        dir.path(),
    );
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("s3://no-such-bucket/e:"), "{err}");
    assert!(err.contains("s3:ListBucket"), "{err}");
    assert!(
        !text(&o.stdout).contains("file "),
        "no work before the error"
    );
}
