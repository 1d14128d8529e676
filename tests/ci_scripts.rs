//! The CI's helper scripts behave as command-line tools: `--help` prints the usage and starts
//! nothing (no QEMU), a wrong argument is a usage error (exit 2).

use std::process::Command;
use std::time::{Duration, Instant};

fn qemu_serial(args: &[&str]) -> (Option<i32>, String, String, Duration) {
    let started = Instant::now();
    let out = Command::new("python3")
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/.ci/qemu_serial.py"))
        .args(args)
        .output()
        .expect("python3");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
        started.elapsed(),
    )
}

#[test]
fn qemu_serial_help_starts_nothing() {
    for flag in ["--help", "-h"] {
        let (code, out, err, took) = qemu_serial(&[flag]);
        assert_eq!(code, Some(0), "{err}");
        assert!(out.contains("Usage: python3 .ci/qemu_serial.py"), "{out}");
        assert!(err.is_empty(), "nothing but the help: {err}");
        // Python's start-up only: QEMU is never started.
        assert!(took < Duration::from_secs(5), "{took:?}");
    }
    let (code, _, err, _) = qemu_serial(&["--bogus"]);
    assert_eq!(code, Some(2), "{err}");
}
