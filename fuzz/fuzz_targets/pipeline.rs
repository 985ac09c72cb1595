//! Pipeline TOML: no panic; a pipeline that loads passes its own checks.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    railgrip::fuzzing::pipeline_bytes(data);
});
