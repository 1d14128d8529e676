//! The conventions `rlg-cal` shares with `rlg-sim` (host-cli): a reader of stdout that goes
//! away ends the run quietly with exit 0, `completions <shell>` prints a script that knows
//! every subcommand, `--version` answers at the top and in each subcommand; and a build for
//! real boards only (no feature `sim`) says so for what needs the simulated board.

use std::process::{Command, Output, Stdio};

fn rlg_cal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rlg-cal"))
        .args(args)
        .stdin(Stdio::null())
        .output()
        .unwrap()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// The bash completion script names every subcommand and a subcommand's flags (those of the
/// simulated board too, in a build with it).
#[test]
fn completions_know_every_subcommand() {
    let out = rlg_cal(&["completions", "bash"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let script = text(&out.stdout);
    assert!(script.len() > 1000, "{} bytes", script.len());
    for word in [
        "rlg-cal",
        "status",
        "calibrate",
        "stream",
        "record",
        "thermal",
        "console",
        "key-provision",
        "completions",
        "--key-file",
        "--accept",
    ] {
        assert!(script.contains(word), "{word} not in the script");
    }
    if cfg!(feature = "sim") {
        for word in ["sweep", "serve-sim", "--sim-state"] {
            assert!(script.contains(word), "{word} not in the script");
        }
    }
}

/// `--version` at the top and after a subcommand: the package's version, exit 0, no board.
#[test]
fn version_everywhere() {
    // clap names a subcommand's version by the path to it: `rlg-cal-status 0.1.0`.
    let version = env!("CARGO_PKG_VERSION");
    for (args, name) in [
        (&["--version"][..], "rlg-cal"),
        (&["-V"], "rlg-cal"),
        (&["status", "--version"], "rlg-cal-status"),
    ] {
        let out = rlg_cal(args);
        assert_eq!(out.status.code(), Some(0), "{args:?}");
        assert_eq!(
            text(&out.stdout).trim(),
            format!("{name} {version}"),
            "{args:?}"
        );
    }
}

/// Runs `rlg-cal args`, reads `lines` lines of its stdout and closes it: (exit status, those
/// lines, stderr).
#[cfg(feature = "sim")]
fn head(args: &[&str], lines: usize) -> (Option<i32>, Vec<String>, String) {
    use std::io::{BufRead, BufReader};
    let mut child = Command::new(env!("CARGO_BIN_EXE_rlg-cal"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut reader = BufReader::new(child.stdout.take().unwrap()).lines();
    let read: Vec<String> = reader.by_ref().take(lines).map(Result::unwrap).collect();
    drop(reader);
    let out = child.wait_with_output().unwrap();
    (out.status.code(), read, text(&out.stderr))
}

/// `rlg-cal --sim record --csv /dev/stdout | head -2` and the same for `stream`: the lines
/// arrive, then exit 0 with nothing on stderr but the announcement of the run (no "Broken
/// pipe"). The recording stops at the first row that cannot be written: 60 s of the board's
/// output would take about a minute of CPU in a test build.
#[cfg(feature = "sim")]
#[test]
fn a_closed_stdout_ends_record_and_stream_quietly() {
    for (command, header) in [
        ("record", "t_s,delta_angle_arcsec,valid,sequence,status"),
        ("stream", "sequence,time_s,end_phase_q32"),
    ] {
        let started = std::time::Instant::now();
        let args = ["--sim", command, "--seconds", "60", "--csv", "/dev/stdout"];
        let (code, lines, stderr) = head(&args, 2);
        assert_eq!(code, Some(0), "{command}: {stderr}");
        assert!(lines[0].starts_with(header), "{command}: {lines:?}");
        let said: Vec<&str> = stderr.lines().collect();
        assert_eq!(said.len(), 1, "{command}: only the announcement: {stderr}");
        assert!(said[0].starts_with("rlg-cal: "), "{stderr}");
        let took = started.elapsed();
        assert!(took.as_secs_f64() < 20.0, "{command}: {took:?}");
    }
}

/// `rlg-cal sweep | head -1` (the table goes to stdout): the header, then a quiet exit 0.
#[cfg(feature = "sim")]
#[test]
fn a_closed_stdout_ends_sweep_quietly() {
    let args = [
        "sweep",
        "--azimuths",
        "0,90",
        "--settle",
        "0.5",
        "--seconds",
        "0.5",
    ];
    let (code, lines, stderr) = head(&args, 1);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(lines[0].starts_with("azimuth_deg,"), "{lines:?}");
    assert!(!stderr.contains("rlg-cal:"), "no error: {stderr}");
}

/// Without the simulated board, its subcommands and `--sim` are usage errors that say why;
/// the board commands still parse and fail only for want of a connection.
#[cfg(not(feature = "sim"))]
#[test]
fn a_build_for_real_boards_says_what_it_lacks() {
    for args in [
        &["--sim", "status"][..],
        &["sweep"],
        &["serve-sim", "--pty"],
    ] {
        let out = rlg_cal(args);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(
            stderr.contains("needs the simulated board") && stderr.contains("feature `sim`"),
            "{args:?}: {stderr}"
        );
    }
    let help = text(&rlg_cal(&["--help"]).stdout);
    assert!(!help.contains("serve-sim  "), "hidden: {help}");
    let out = rlg_cal(&["--tcp", "127.0.0.1:1", "status"]);
    assert_eq!(out.status.code(), Some(3), "{}", text(&out.stderr));
}
