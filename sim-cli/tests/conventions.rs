//! The conventions `rlg-sim` shares with `rlg-cal` (host-cli): a reader of stdout that goes
//! away ends the run quietly with exit 0, `completions <shell>` prints a script that knows
//! every subcommand, `--version` answers at the top and in each subcommand, and `--help`
//! lists the exit statuses.

mod support;

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use support::{rlg_sim, text};

/// `rlg-sim record --csv /dev/stdout | head -2`: the two lines arrive, the reader closes the
/// pipe, and the run ends with exit 0 and nothing on stderr after the calibration's two lines
/// (no "Broken pipe", no panic). The record would take 30 s of gyro time; stopping at the
/// first failed write is what makes it end well before.
#[test]
fn a_closed_stdout_ends_record_quietly() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_rlg-sim"))
        .args([
            "record",
            "--seconds",
            "30",
            "--csv",
            "/dev/stdout",
            "--quiet",
        ])
        .args(["--calibration-seconds", "5"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let started = std::time::Instant::now();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let head: Vec<String> = lines.by_ref().take(2).map(Result::unwrap).collect();
    drop(lines);
    let out = child.wait_with_output().unwrap();
    let took = started.elapsed();
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert_eq!(
        head[0],
        "t_s,delta_angle_arcsec,true_delta_angle_arcsec,valid"
    );
    assert_eq!(head[1].split(',').count(), 4, "{}", head[1]);
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 2, "only the calibration's lines: {stderr}");
    assert!(lines[0].starts_with("calibration at") && lines[1].contains("Omega_L"));
    // 30 s of record take about 12 s of CPU in a test build; the run stops at once instead.
    assert!(took.as_secs_f64() < 10.0, "{took:?}");
}

/// `rlg-sim sweep | head -1`: the table's first line, then a quiet exit 0.
#[test]
fn a_closed_stdout_ends_sweep_quietly() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_rlg-sim"))
        .args([
            "sweep",
            "--quiet",
            "--points",
            "3",
            "--seconds-per-point",
            "0.2",
        ])
        .args(["--calibration-seconds", "5"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert_eq!(
        stderr.lines().count(),
        2,
        "only the calibration's lines: {stderr}"
    );
}

/// The bash completion script names every subcommand and a subcommand's flags.
#[test]
fn completions_know_every_subcommand() {
    let (out, _) = rlg_sim(&["completions", "bash"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let script = text(&out.stdout);
    assert!(script.len() > 1000, "{} bytes", script.len());
    for word in [
        "rlg-sim",
        "sweep",
        "speed",
        "dither",
        "record",
        "allan",
        "characterize",
        "completions",
        "--seconds-per-point",
    ] {
        assert!(script.contains(word), "{word} not in the script");
    }
    let (out, _) = rlg_sim(&["completions", "tcsh"]);
    assert_eq!(
        out.status.code(),
        Some(2),
        "an unknown shell is a usage error"
    );
}

/// `--version` at the top and after a subcommand: the package's version, exit 0.
#[test]
fn version_everywhere() {
    // clap names a subcommand's version by the path to it: `rlg-sim-record 0.1.0`.
    let version = env!("CARGO_PKG_VERSION");
    for (args, name) in [
        (&["--version"][..], "rlg-sim"),
        (&["-V"], "rlg-sim"),
        (&["record", "--version"], "rlg-sim-record"),
    ] {
        let (out, _) = rlg_sim(args);
        assert_eq!(out.status.code(), Some(0), "{args:?}");
        assert_eq!(
            text(&out.stdout).trim(),
            format!("{name} {version}"),
            "{args:?}"
        );
    }
}

/// `rlg-sim --help` lists every exit status it gives, each with its meaning; `-h` is the
/// short form without them.
#[test]
fn help_lists_the_exit_statuses() {
    let out = rlg_sim(&["--help"]).0;
    assert_eq!(out.status.code(), Some(0));
    let help = text(&out.stdout);
    for line in [
        "Exit status:",
        "  0    success, also when the reader of stdout goes away",
        "  1    a run failed",
        "  2    usage error",
        "  130  stopped by Ctrl-C or SIGTERM",
    ] {
        assert!(help.contains(line), "{line:?} in {help}");
    }
    let short = text(&rlg_sim(&["-h"]).0.stdout);
    assert!(!short.contains("Exit status"), "{short}");
}
