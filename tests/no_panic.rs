//! No input panics a reader: random bytes and mutated valid logs, CSV and MCAP (bounded).

mod common;

use std::fs;

use common::*;
use proptest::prelude::*;
use railgrip::format::McapCompression;
use railgrip::ingest::ingest_file;
use railgrip::Pipeline;

fn seeds() -> (Vec<u8>, Vec<u8>) {
    let csv = Table::analytic(0.3, 417.0, 0.2, 3).csv_bytes();
    let mcap = MultiRate::analytic(0.3, 100.0, 417.0, 200.0, 0.2, 4)
        .mcap_bytes(&soap_metadata(), McapCompression::Zstd);
    (csv, mcap)
}

/// Feeds bytes to ingest through a file; any outcome but a panic is fine, and an error must
/// name the file.
fn feed(bytes: &[u8], name: &str) {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join(name);
    fs::write(&p, bytes).unwrap();
    if let Err(e) = ingest_file(&p, &Pipeline::default_uic_z1()) {
        assert!(
            e.to_string().contains(name),
            "error does not name the file: {e}"
        );
    }
}

#[derive(Debug, Clone)]
enum Mutation {
    Flip(usize, u8),
    Truncate(usize),
    Insert(usize, Vec<u8>),
    Delete(usize, usize),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), 1u8..=255).prop_map(|(i, x)| Mutation::Flip(i, x)),
        any::<usize>().prop_map(Mutation::Truncate),
        (
            any::<usize>(),
            proptest::collection::vec(any::<u8>(), 1..16)
        )
            .prop_map(|(i, b)| Mutation::Insert(i, b)),
        (any::<usize>(), 1usize..64).prop_map(|(i, n)| Mutation::Delete(i, n)),
    ]
}

fn apply(base: &[u8], ms: &[Mutation]) -> Vec<u8> {
    let mut b = base.to_vec();
    for m in ms {
        if b.is_empty() {
            break;
        }
        match m {
            Mutation::Flip(i, x) => {
                let k = i % b.len();
                b[k] ^= x;
            }
            Mutation::Truncate(i) => b.truncate(i % b.len()),
            Mutation::Insert(i, bytes) => {
                let k = i % b.len();
                b.splice(k..k, bytes.iter().copied());
            }
            Mutation::Delete(i, n) => {
                let k = i % b.len();
                let e = (k + n).min(b.len());
                b.drain(k..e);
            }
        }
    }
    b
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..2048), prefix in 0u8..3) {
        let mut b = match prefix {
            0 => Vec::new(),
            1 => mcap::MAGIC.to_vec(),
            _ => b"t,v_radar,omega1,omega2,omega3,omega4,p1,p2,p3,p4\n".to_vec(),
        };
        b.extend(bytes);
        feed(&b, "random.bin");
    }

    #[test]
    fn mutated_csv_never_panics(ms in proptest::collection::vec(mutation(), 1..4)) {
        let (csv, _) = seeds();
        feed(&apply(&csv, &ms), "mutated.csv");
    }

    #[test]
    fn mutated_mcap_never_panics(ms in proptest::collection::vec(mutation(), 1..4)) {
        let (_, mcap) = seeds();
        feed(&apply(&mcap, &ms), "mutated.mcap");
    }
}

/// The committed seed corpus of a fuzz target (`fuzz/corpus/<target>/`, made by
/// `fuzz/make_corpus.sh`).
fn corpus(target: &str) -> Vec<Vec<u8>> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/corpus")
        .join(target);
    let mut files: Vec<_> = fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    let seeds: Vec<Vec<u8>> = files.iter().map(|p| fs::read(p).unwrap()).collect();
    assert!(!seeds.is_empty(), "{}: empty corpus", dir.display());
    seeds
}

// The bounded versions of the fuzz targets (fuzz/fuzz_targets/*.rs call the same
// railgrip::fuzzing functions; docs/limits.md#fuzzing has the ≥ 10⁶-input runs).
proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn mutated_mcap_messages_never_panic(ms in proptest::collection::vec(mutation(), 1..4), k in any::<usize>()) {
        let seeds = corpus("mcap_message");
        railgrip::fuzzing::mcap_message_bytes(&apply(&seeds[k % seeds.len()], &ms));
    }

    #[test]
    fn mutated_sidecars_never_panic(ms in proptest::collection::vec(mutation(), 1..4), k in any::<usize>()) {
        let seeds = corpus("sidecar");
        railgrip::fuzzing::sidecar_bytes(&apply(&seeds[k % seeds.len()], &ms));
    }

    #[test]
    fn mutated_pipelines_never_panic(ms in proptest::collection::vec(mutation(), 1..4)) {
        railgrip::fuzzing::pipeline_bytes(&apply(&corpus("pipeline")[0], &ms));
    }

    #[test]
    fn mutated_scenes_never_panic(ms in proptest::collection::vec(mutation(), 1..4), k in any::<usize>()) {
        let seeds = corpus("scene");
        railgrip::fuzzing::scene_bytes(&apply(&seeds[k % seeds.len()], &ms));
    }

    #[test]
    fn mutated_model_files_never_panic(ms in proptest::collection::vec(mutation(), 1..4), k in any::<usize>()) {
        let seeds = corpus("model");
        railgrip::fuzzing::model_bytes(&apply(&seeds[k % seeds.len()], &ms));
    }

    #[test]
    fn mutated_corpus_logs_never_panic(ms in proptest::collection::vec(mutation(), 1..4), k in any::<usize>()) {
        let (csv, mcap) = (corpus("csv"), corpus("mcap"));
        railgrip::fuzzing::log_bytes(&apply(&csv[k % csv.len()], &ms), "fuzz.csv", None);
        railgrip::fuzzing::log_bytes(&apply(&mcap[k % mcap.len()], &ms), "fuzz.mcap", None);
    }
}

#[test]
fn the_fuzz_seeds_are_valid_inputs() {
    // Seeds that already fail would fuzz the error paths only.
    for s in corpus("pipeline") {
        railgrip::Pipeline::from_toml(std::str::from_utf8(&s).unwrap(), "seed.toml").unwrap();
    }
    for s in corpus("model") {
        railgrip::model::ModelFile::from_json(std::str::from_utf8(&s).unwrap(), "seed.json")
            .unwrap();
    }
    for s in corpus("csv").iter().chain(&corpus("mcap")) {
        let src = railgrip::ingest::LogSource::Memory {
            name: "seed".into(),
            bytes: s.as_slice().into(),
            sidecar: None,
        };
        railgrip::ingest::ingest_source(&src, &railgrip::Pipeline::default_uic_z1()).unwrap();
    }
    for s in corpus("mcap_message") {
        let (encoding, name, _, paths) = railgrip::fuzzing::MCAP_MESSAGE_PATHS[(s[0] % 2) as usize];
        let len = u16::from_le_bytes([s[1], s[2]]) as usize;
        let (schema, payload) = s[3..].split_at(len);
        let d = railgrip::ingest::MessageDecoder::new(encoding, name, schema, paths, true).unwrap();
        let v = d.extract(payload, &[]).unwrap();
        assert!(v.iter().all(|x| x.is_some_and(f64::is_finite)), "{v:?}");
    }
}

#[test]
fn a_csv_that_panicked_the_polars_reader_is_a_clean_error() {
    // Found by the csv fuzz target: polars 0.55 panics in csv/read/builder.rs:141
    // on this file; `railgrip ingest` exited 101 and `railgrip run` lost the whole campaign.
    let bytes = std::fs::read(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/fuzz/polars_panic_builder_141.csv"),
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("found.csv");
    fs::write(&p, &bytes).unwrap();
    let e = ingest_file(&p, &Pipeline::default_uic_z1())
        .unwrap_err()
        .to_string();
    assert!(e.contains("found.csv: line"), "{e}");
    railgrip::fuzzing::log_bytes(&bytes, "fuzz.csv", None);
}
