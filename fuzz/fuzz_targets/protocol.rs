//! Coverage-guided fuzzing of the serial protocol (parser and executor); the checks are in
//! `src/lib.rs`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| rlg_protocol_fuzz::check(data));
