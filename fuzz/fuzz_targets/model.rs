//! Model-file JSON: no panic; a file that loads evaluates to finite μ and exports a header.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    railgrip::fuzzing::model_bytes(data);
});
