//! A metadata sidecar beside a small valid CSV log: no panic, errors name the file.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    railgrip::fuzzing::sidecar_bytes(data);
});
