//! An MCAP log from memory through ingest and the estimator: no panic, errors name the file.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    railgrip::fuzzing::log_bytes(data, "fuzz.mcap", None);
});
