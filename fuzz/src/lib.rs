//! Coverage-guided fuzzing of what anyone on the serial line, or a damaged flash, can feed the
//! firmware and the host tool. One module per target, each with the promises it checks:
//!
//! | target | module | reaches |
//! |---|---|---|
//! | `protocol` | [`protocol`] | line assembler, checksum, parser, executor (in-memory device), unprovisioned boards and `key provision`, new sessions |
//! | `service` | [`service`] | the command service's main-loop pass, the record queue with lost cycles, output records, new sessions, resets with the wrong-key count kept, failing flash writes |
//! | `device` | [`device`] | hal-sim's simulated board: the flash stall and what waits for it, new sessions during stalls, power cycles and cuts |
//! | `decoders` | [`decoders`] | COBS, the cycle and output frame decoders, calibration record decoding, the store's log scan and a store after it |
//! | `host` | [`host`] | `rlg-cal`'s answer checker, fields and JSON, the client reading an answer, the stream capture and CSV, the output recording's rows |
//!
//! Two drivers share this crate: the `cargo fuzz` targets (`fuzz/fuzz_targets/`, CI through
//! `fuzz/run.sh`, seeded from `fuzz/seeds/<target>/`, the line-driven ones with the dictionary
//! `fuzz/protocol.dict`) and seeded, bounded random mutations in every `cargo test`
//! (`host-tool/tests/protocol_fuzz.rs`, which includes this file by path).

pub mod answers;
pub mod decoders;
pub mod device;
pub mod events;
pub mod host;
pub mod protocol;
pub mod service;
