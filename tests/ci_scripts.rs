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

/// The reference client and its CI runner print their usage and start nothing; a missing
/// argument is a usage error (exit 2). The RAM-code check without an image prints its usage.
#[test]
fn reference_client_and_ram_check_print_their_usage() {
    let run = |script: &str, args: &[&str]| {
        let out = Command::new("python3")
            .arg(format!("{}/{script}", env!("CARGO_MANIFEST_DIR")))
            .args(args)
            .output()
            .expect("python3");
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).into_owned()
                + &String::from_utf8_lossy(&out.stderr),
        )
    };
    let (code, out) = run("clients/python/rlg_client.py", &["--help"]);
    assert_eq!(code, Some(0), "{out}");
    assert!(out.contains("check"), "{out}");
    let (code, out) = run("clients/python/rlg_client.py", &["check", "--rate", "15"]);
    assert_eq!(code, Some(2), "no connection given: {out}");
    let (code, out) = run(".ci/reference_client.py", &["--help"]);
    assert_eq!(code, Some(0), "{out}");
    assert!(out.contains("RLG_CAL"), "{out}");
    let (code, out) = run(".ci/reference_client.py", &[]);
    assert_eq!(code, Some(2), "{out}");
    let (code, out) = run(".ci/ram_code.py", &[]);
    assert_eq!(code, Some(1), "{out}");
    assert!(out.contains("Usage: python3 .ci/ram_code.py"), "{out}");
}
