//! The `rlg-sim` binary as a user runs it: a calibration the board would refuse exits 1 naming
//! the board's reason, and a bad output path is refused before the run.

mod support;

use std::io::{BufRead, BufReader};
use std::process::{Command, Output, Stdio};
use std::time::Duration;
use support::{rlg_sim, text};

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

/// The default calibration passes the board's checks: docs/results.md's fit on the default
/// (realistic) board, Omega_L 200.010 deg/h, eps 0.29997 rad, and exit 0. (Two points of 1 s:
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
        stderr.contains("Omega_L = 200.010 deg/h") && stderr.contains("eps = 0.29997 rad"),
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

/// Starts `rlg-sim` with `args` and waits until it has printed its calibration (the long
/// work under way): the child and its stderr.
fn spawn_calibrated(args: &[&str]) -> (std::process::Child, BufReader<std::process::ChildStderr>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_rlg-sim"))
        .args(args)
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
    (child, stderr)
}

/// SIGINT to `child`, then its output and the rest of its stderr once it has ended.
fn interrupt(
    child: std::process::Child,
    mut stderr: BufReader<std::process::ChildStderr>,
) -> (Output, String) {
    // SAFETY: a signal to our own child process.
    assert_eq!(
        unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) },
        0
    );
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut stderr, &mut rest).unwrap();
    (child.wait_with_output().unwrap(), rest)
}

/// Ctrl-C after the calibration: the input rates under way finish, the rest are skipped; the
/// table and the CSV hold the rates done (the same rows), and the exit status is 130.
#[test]
fn sigint_keeps_the_points_done() {
    let csv = std::env::temp_dir().join(format!("rlg-sim-int-{}.csv", std::process::id()));
    let csv_arg = csv.to_str().unwrap();
    let (child, stderr) = spawn_calibrated(&[
        "sweep",
        "--quiet",
        "--calibration-seconds",
        "5",
        "--csv",
        csv_arg,
    ]);
    std::thread::sleep(Duration::from_millis(500));
    let (out, rest) = interrupt(child, stderr);
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

/// `rlg-sim record`: rows reach the disk as they come; Ctrl-C a second into the recording stops
/// the run cleanly: exit 130, the header and every row written (about 1000 rows per simulated
/// second at the default 1 kHz sync; the run simulates several seconds per wall second), the
/// last row complete.
#[test]
fn record_sigint_keeps_every_row() {
    let csv = std::env::temp_dir().join(format!("rlg-sim-rec-{}.csv", std::process::id()));
    let csv_arg = csv.to_str().unwrap();
    let (child, stderr) = spawn_calibrated(&[
        "record",
        "--quiet",
        "--calibration-seconds",
        "3",
        "--seconds",
        "600",
        "--csv",
        csv_arg,
    ]);
    std::thread::sleep(Duration::from_millis(1500));
    // Rows are on disk before the run ends (flushed at least once a second).
    let early = std::fs::read_to_string(&csv).unwrap().lines().count();
    assert!(early > 1, "{early} lines after 1.5 s");
    let (out, rest) = interrupt(child, stderr);
    assert_eq!(out.status.code(), Some(130), "{rest}");
    let written = std::fs::read_to_string(&csv).unwrap();
    let mut lines = written.lines();
    assert_eq!(
        lines.next(),
        Some("t_s,delta_angle_arcsec,true_delta_angle_arcsec,valid")
    );
    let rows: Vec<&str> = lines.collect();
    assert!(rows.len() >= early - 1, "{} < {early}", rows.len());
    assert!(written.ends_with('\n'));
    for row in &rows {
        let fields: Vec<f64> = row.split(',').map(|f| f.parse().unwrap()).collect();
        assert_eq!(fields.len(), 4, "{row}");
    }
    let stdout = text(&out.stdout);
    assert!(stdout.contains(&format!("{} rows", rows.len())), "{stdout}");
    let _ = std::fs::remove_file(&csv);
}

/// Out-of-range board flags are refused at once, naming the flag and its range.
#[test]
fn record_refuses_out_of_range_flags() {
    for (flag, value, says) in [
        ("--sync-hz", "50", "50 is outside 100..=2000 Hz"),
        ("--pickoff-lag-us", "-1", "-1 is outside 0..=100 us"),
        ("--pickoff-gain-error", "-0.5", "-0.5 is outside -0.2..=0.2"),
        ("--seconds", "0", "0 is outside 0 < x <= 360000 s"),
    ] {
        let (out, took) = rlg_sim(&["record", "--csv", "/tmp/never.csv", flag, value]);
        assert_eq!(out.status.code(), Some(2), "{flag} {value}");
        let says = format!("for '{flag} <{}>': {says}", clap_name(flag));
        assert!(text(&out.stderr).contains(&says), "{}", text(&out.stderr));
        assert!(took < Duration::from_secs(1), "{took:?}");
    }
}

/// How clap names a flag's value in its messages: `--sync-hz` -> `SYNC_HZ`.
fn clap_name(flag: &str) -> String {
    flag.trim_start_matches("--")
        .replace('-', "_")
        .to_uppercase()
}

/// Every numeric flag takes a leading minus where the value is legal (the error that follows
/// is about a later flag, and clap parses in order, so the negative one was accepted), and refuses
/// an out-of-range value with its flag and range, exit 2, within a second (`--dither-hz 0` and
/// an amplitude of 1e9 arcsec would hang a run, `--eps-rad 1e300` would print garbage).
#[test]
fn numeric_flags_take_negatives_where_legal_and_state_their_ranges() {
    for legal in [
        ["--eps-rad", "-0.7"],
        ["--rate-min-deg-h", "-6"],
        ["--pickoff-gain-error", "-0.05"],
        ["--calibration-rate-deg-h", "-13.888"],
    ] {
        let mut args = vec!["sweep"];
        args.extend_from_slice(&legal);
        args.extend_from_slice(&["--sync-hz", "50"]);
        let (out, took) = rlg_sim(&args);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{legal:?}");
        assert!(
            stderr.contains("for '--sync-hz <SYNC_HZ>': 50 is outside"),
            "{legal:?}: {stderr}"
        );
        assert!(took < Duration::from_secs(1), "{took:?}");
    }
    for (flag, value, says) in [
        ("--dither-hz", "0", "0 is outside 200..=1500 Hz"),
        (
            "--dither-amplitude-arcsec",
            "1e9",
            "1e9 is outside 50..=800 arcsec",
        ),
        ("--eps-rad", "1e300", "1e300 is outside -pi..=pi rad"),
        ("--arw-deg-rt-h", "-1", "-1 is outside 0..=1 deg/sqrt(h)"),
        ("--lock-in-deg-h", "-5", "-5 is outside 0..=5000 deg/h"),
        (
            "--scale-factor-arcsec",
            "-1.8655",
            "-1.8655 is outside 0.1..=20 arcsec",
        ),
        (
            "--seconds-per-point",
            "-10",
            "-10 is outside 0.001..=36000 s",
        ),
        (
            "--amplitude-jitter",
            "nan",
            "nan is not a finite number in 0..=0.1",
        ),
        ("--points", "0", "0 is outside 1..=10000"),
        (
            "--rate-max-deg-h",
            "-2e6",
            "-2e6 is outside -1e6..=1e6 deg/h",
        ),
        (
            "--warmup-seconds",
            "inf",
            "inf is not a finite number in 0..=60 s",
        ),
    ] {
        let (out, took) = rlg_sim(&["sweep", flag, value]);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{flag} {value}: {stderr}");
        let says = format!("for '{flag} <{}>': {says}", clap_name(flag));
        assert!(stderr.contains(&says), "{flag} {value}: {stderr}");
        assert!(took < Duration::from_secs(1), "{flag}: {took:?}");
    }
}

/// `rlg-sim speed` times the bare gyro and, with `--board`, the simulated board with the
/// firmware in the loop (the figure of a long `record`): both print a positive speed and
/// name what they timed; a bad length is refused (exit 2) before anything runs.
#[test]
fn speed_times_the_gyro_and_the_board() {
    for (args, what) in [
        (&["speed", "--seconds", "0.2"][..], "of the gyro:"),
        (
            &["speed", "--board", "--seconds", "0.2", "--rate-deg-h", "-3"][..],
            "of the simulated board",
        ),
    ] {
        let (out, _) = rlg_sim(args);
        let stdout = text(&out.stdout);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{args:?}: {}",
            text(&out.stderr)
        );
        assert!(stdout.contains(what), "{stdout}");
        let speed: f64 = stdout
            .split(": ")
            .nth(1)
            .and_then(|r| r.split_whitespace().next())
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("no speed in {stdout}"));
        assert!(speed > 0.0, "{stdout}");
    }
    let (out, took) = rlg_sim(&["speed", "--board", "--seconds", "0"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("'--seconds <SECONDS>': 0 is outside 0 < x <= 3600 s"));
    assert!(took < Duration::from_secs(1), "{took:?}");
}

/// The thermal flags: a malformed or out-of-range profile and an out-of-range coefficient are
/// refused at once (exit 2), naming the flag and its range.
#[test]
fn thermal_flags_are_range_checked() {
    for (flag, value, says) in [
        (
            "--temperature-profile",
            "ramp:0:10",
            "--temperature-profile \"ramp:0:10\": unknown kind or wrong number of fields",
        ),
        (
            "--temperature-profile",
            "constant:200",
            "temperature 200 outside -55..=150 C",
        ),
        (
            "--thermal-sf-ppm-per-c",
            "200",
            "'--thermal-sf-ppm-per-c <THERMAL_SF_PPM_PER_C>': 200 is outside -100..=100 ppm per C",
        ),
        (
            "--thermal-bias-deg-h-per-c-per-min",
            "-2",
            "<THERMAL_BIAS_DEG_H_PER_C_PER_MIN>': -2 is outside -1..=1 deg/h per C/min",
        ),
        (
            "--thermal-eps-rad-per-c",
            "0.1",
            "'--thermal-eps-rad-per-c <THERMAL_EPS_RAD_PER_C>': 0.1 is outside -0.05..=0.05 rad per C",
        ),
    ] {
        let (out, took) = rlg_sim(&["record", "--csv", "/tmp/never.csv", flag, value]);
        assert_eq!(out.status.code(), Some(2), "{flag} {value}");
        assert!(text(&out.stderr).contains(says), "{}", text(&out.stderr));
        assert!(took < Duration::from_secs(1), "{took:?}");
    }
}

/// `record --temperature-profile` adds the `temperature_c` column: the temperature the board's
/// records carry (its simulated TMP117), which follows a 20 -> 30 °C ramp at 1 °C/s to within
/// the sensor's accuracy and its lag (0.02 °C offset, a result every 125 ms read within 50 ms:
/// up to 0.2 °C behind at 1 °C/s, bounded at 0.3); without a profile the column is absent.
#[test]
fn record_with_a_temperature_profile_has_the_temperature_column() {
    let csv = std::env::temp_dir().join(format!("rlg-sim-temp-{}.csv", std::process::id()));
    let path = csv.to_str().unwrap();
    let (out, _) = rlg_sim(&[
        "record",
        "--quiet",
        "--rate-deg-h",
        "13.888",
        "--seconds",
        "4",
        "--calibration-seconds",
        "5",
        "--temperature-profile",
        "ramp:20:30:60",
        "--csv",
        path,
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let rows = std::fs::read_to_string(&csv).unwrap();
    let mut lines = rows.lines();
    assert_eq!(
        lines.next(),
        Some("t_s,delta_angle_arcsec,true_delta_angle_arcsec,valid,temperature_c")
    );
    let mut worst: f64 = 0.0;
    for line in lines {
        let fields: Vec<&str> = line.split(',').collect();
        let t: f64 = fields[0].parse().unwrap();
        let temp: f64 = fields[4].parse().unwrap();
        let truth = (20.0 + t).min(30.0);
        worst = worst.max((temp - truth).abs());
    }
    assert!(worst < 0.3 && worst > 0.05, "{worst}");
    let (out, _) = rlg_sim(&[
        "record",
        "--quiet",
        "--seconds",
        "0.1",
        "--calibration-seconds",
        "5",
        "--csv",
        path,
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let rows = std::fs::read_to_string(&csv).unwrap();
    assert!(rows.starts_with("t_s,delta_angle_arcsec,true_delta_angle_arcsec,valid\n"));
    let _ = std::fs::remove_file(&csv);
}
