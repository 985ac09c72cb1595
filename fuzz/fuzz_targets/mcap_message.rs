//! One protobuf or ROS 2 CDR message with its schema (see `railgrip::fuzzing::mcap_message_bytes`):
//! no panic while building the decoder from the schema or reading the payload.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    railgrip::fuzzing::mcap_message_bytes(data);
});
