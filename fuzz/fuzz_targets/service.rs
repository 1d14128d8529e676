//! The `service` target; its checks are in `src/service.rs`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| rlg_protocol_fuzz::service::check(data));
