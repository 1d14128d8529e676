//! What the `rlg-sim` CLI tests share: running the binary as a user would, and its output.

use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// Runs `rlg-sim` with `args` (no stdin) to completion: its output and how long it took.
pub fn rlg_sim(args: &[&str]) -> (Output, Duration) {
    let started = Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_rlg-sim"))
        .args(args)
        .stdin(Stdio::null())
        .output()
        .unwrap();
    (out, started.elapsed())
}

/// Bytes of stdout or stderr as text.
pub fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}
