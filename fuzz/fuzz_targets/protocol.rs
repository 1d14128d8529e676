//! The `protocol` target; its checks are in `src/protocol.rs`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| rlg_protocol_fuzz::protocol::check(data));
