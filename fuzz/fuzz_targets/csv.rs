//! A CSV log from memory through ingest and, when it reads, the estimator: no panic, and an
//! error names the file.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    railgrip::fuzzing::log_bytes(data, "fuzz.csv", None);
});
