//! Scene TOML: no panic.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    railgrip::fuzzing::scene_bytes(data);
});
