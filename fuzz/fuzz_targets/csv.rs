//! A CSV log from memory through ingest and, when it reads, the estimator: no panic, and an
//! error names the file.
//!
//! libFuzzer's panic hook aborts on every panic, also on one the library catches: polars 0.55
//! panics in its CSV worker threads on some malformed rows (railgrip catches that and reports
//! the line; tests/data/fuzz/). Panics on `polars-N` threads therefore go to the default hook
//! only when they escape (then the target still fails); all others abort as usual.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(
    init: {
        let fuzzer_hook = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let polars = std::thread::current()
                .name()
                .is_some_and(|n| n.starts_with("polars"));
            if !polars {
                fuzzer_hook(info);
            }
        }));
    },
    |data: &[u8]| {
        railgrip::fuzzing::log_bytes(data, "fuzz.csv", None);
    }
);
