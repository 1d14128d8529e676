//! The `rlg-sim` binary as a user runs it: a calibration the board would refuse exits 1 naming
//! the board's reason, and a bad output path is refused before the run.

use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn rlg_sim(args: &[&str]) -> (Output, Duration) {
    let started = Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_rlg-sim"))
        .args(args)
        .stdin(Stdio::null())
        .output()
        .unwrap();
    (out, started.elapsed())
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Calibrating at 0 deg/h (inside the dead band) and on 0.05 s per run (38 cycles; the board
/// needs 2000) is refused with the firmware's reason codes 1 and 2 and their words, exit 1,
/// and no sweep table is printed.
#[test]
fn a_calibration_the_board_refuses_exits_1_with_its_reason() {
    for (args, reason) in [
        (
            &["--calibration-rate-deg-h", "0"][..],
            "reason=1 (mean rate inside the dynamic dead band)",
        ),
        (
            &["--calibration-seconds", "0.05"][..],
            "reason=2 (too few cycles)",
        ),
    ] {
        let mut all = vec!["sweep", "--quiet", "--points", "2"];
        all.extend_from_slice(args);
        let (out, _) = rlg_sim(&all);
        let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(stderr.contains(reason), "{args:?}: {stderr}");
        assert!(!stdout.contains("max |output - ideal|"), "{stdout}");
    }
}

/// The default calibration passes the board's checks: the README's fit on the default
/// (realistic) board, Omega_L 199.652 deg/h, eps 0.30001 rad, and exit 0. (Two points of 1 s:
/// the calibration is the defaults'.)
#[test]
fn the_default_calibration_passes() {
    let (out, _) = rlg_sim(&[
        "sweep",
        "--quiet",
        "--points",
        "2",
        "--seconds-per-point",
        "1",
    ]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(
        stderr.contains("Omega_L = 199.652 deg/h") && stderr.contains("eps = 0.30001 rad"),
        "{stderr}"
    );
}

/// `--svg` / `--csv` into a missing directory: usage error (2) in well under a second, before
/// the calibration starts (which alone takes longer).
#[test]
fn a_bad_output_path_fails_before_the_run() {
    for flag in ["--svg", "--csv"] {
        let (out, took) = rlg_sim(&["sweep", "--quiet", flag, "/nonexistent/dir/x.svg"]);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{flag}: {stderr}");
        assert!(stderr.contains("/nonexistent/dir/x.svg"), "{stderr}");
        assert!(took < Duration::from_millis(500), "{flag}: {took:?}");
    }
}

/// Ctrl-C after the calibration: the input rates under way finish, the rest are skipped; the
/// table and the CSV hold the rates done (the same rows), and the exit status is 130.
#[test]
fn sigint_keeps_the_points_done() {
    use std::io::{BufRead, BufReader};
    let csv = std::env::temp_dir().join(format!("rlg-sim-int-{}.csv", std::process::id()));
    let mut child = Command::new(env!("CARGO_BIN_EXE_rlg-sim"))
        .args(["sweep", "--quiet", "--calibration-seconds", "5", "--csv"])
        .arg(&csv)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = BufReader::new(child.stderr.take().unwrap());
    let mut line = String::new();
    while !line.contains("Omega_L") {
        line.clear();
        assert!(stderr.read_line(&mut line).unwrap() > 0, "calibration line");
    }
    std::thread::sleep(Duration::from_millis(500));
    // SAFETY: a signal to our own child process.
    assert_eq!(
        unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) },
        0
    );
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut stderr, &mut rest).unwrap();
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(130), "{rest}");
    assert!(rest.contains("input rates done"), "{rest}");
    let rows = std::fs::read_to_string(&csv).unwrap().lines().count() - 1;
    assert!((1..41).contains(&rows), "{rows} rows");
    let table_rows = text(&out.stdout)
        .lines()
        .filter(|l| {
            l.trim_start()
                .starts_with(['-', '0', '1', '2', '3', '4', '5', '6', '7', '8', '9'])
        })
        .count();
    assert_eq!(table_rows, rows, "{}", text(&out.stdout));
}
