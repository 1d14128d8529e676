//! The `decoders` target; its checks are in `src/decoders.rs`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| rlg_protocol_fuzz::decoders::check(data));
