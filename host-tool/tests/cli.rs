//! The `rlg-cal` binary: help, exit codes, files written, and a served board driven by a
//! second `rlg-cal` process over loopback TCP and a pty.
//!
//! Size (over 600 lines): every test drives the binary through the helpers at the top of this file
//! (`rlg_cal`, `run`, `scratch`, `key_file`).

use std::io::{BufRead, BufReader};
use std::net::TcpListener;
use std::path::PathBuf;
use std::process::{Child, Command, Output, Stdio};

/// The key the `--sim` and served boards of these tests are given (the client's key
/// provisions the `--sim` board; `--board-key-file` the served one).
const TEST_KEY: &str = "3a7c5e91b2d4f60819e3c5a7b9d1f2e4";

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

/// (exit code, stdout, stderr)
fn run(args: &[&str]) -> (i32, String, String) {
    let out = rlg_cal(args);
    (
        out.status.code().unwrap_or(-1),
        text(&out.stdout),
        text(&out.stderr),
    )
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rlg-cal-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// A file holding [`TEST_KEY`] (`--key-file`, `--board-key-file`).
fn key_file() -> String {
    let path = scratch("key");
    std::fs::write(&path, format!("{TEST_KEY}\n")).unwrap();
    path.to_str().unwrap().to_owned()
}

#[test]
fn help_documents_commands_and_exit_codes() {
    let (code, out, _) = run(&["--help"]);
    assert_eq!(code, 0);
    for word in [
        "calibrate",
        "stream",
        "sweep",
        "serve-sim",
        "Exit status",
        "0    success, also when the reader of stdout goes away",
        "3    connection",
        "130  stopped by Ctrl-C",
        "RLG_TCP",
    ] {
        assert!(out.contains(word), "{word} in --help");
    }
    let (code, out, _) = run(&["calibrate", "--help"]);
    assert_eq!(code, 0);
    assert!(out.contains("--accept") && out.contains("--warmup"));
    // Each numeric flag's help states the range its parser enforces.
    for (command, range) in [
        (
            "calibrate",
            "Dither cycles in the fit (1..=3600000 dither cycles)",
        ),
        ("stream", "How long to stream (0 < x <= 86400 s)"),
        ("record", "How long to record (0 < x <= 360000 s)"),
        ("sweep", "Latitude of the rotary table (-90..=90 deg)"),
    ] {
        let (code, out, _) = run(&[command, "--help"]);
        assert_eq!(code, 0);
        assert!(out.contains(range), "{command} --help: {out}");
    }
}

#[test]
fn usage_errors_exit_2() {
    for args in [
        &[][..],
        &["status"],
        &["--sim", "--tcp", "127.0.0.1:1", "status"],
        &["--sim", "set", "c", "1"],
        &["--sim", "set", "a", "twelve"],
        &["--sim", "calibrate", "--store"],
        &["--sim", "sweep"],
    ] {
        let (code, _, err) = run(args);
        assert_eq!(code, 2, "{args:?}: {err}");
    }
}

#[test]
fn the_board_refusing_exits_1_and_says_why() {
    let (code, _, err) = run(&["--sim", "set", "a", "1"]);
    assert_eq!(code, 1);
    assert!(err.contains("ERR 9 locked"), "{err}");
    let kf = key_file();
    let (code, _, err) = run(&["--sim", "--key-file", &kf, "set", "a", "NaN"]);
    assert_eq!(code, 1);
    assert!(err.contains("ERR 4"), "{err}");
    let (code, out, _) = run(&["--sim", "--key-file", &kf, "set", "b", "-344.123456"]);
    assert_eq!((code, out.trim()), (0, "b=-344.12344"));
}

#[test]
fn no_board_exits_3() {
    let port = {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().port()
    }; // closed again: nobody listens there now
    let address = format!("127.0.0.1:{port}");
    let (code, _, err) = run(&["--tcp", &address, "status"]);
    assert_eq!(code, 3, "{err}");
    let (code, _, err) = run(&["--port", "/dev/nonexistent-tty", "status"]);
    assert_eq!(code, 3, "{err}");
}

#[test]
fn calibrate_with_accept_and_store() {
    let kf = key_file();
    let (code, out, err) = run(&[
        "--sim",
        "--key-file",
        &kf,
        "calibrate",
        "--cycles",
        "3000",
        "--warmup",
        "100",
        "--accept",
        "--store",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("\nlock_in_deg_h=") && out.contains("\naccept.comp=on"),
        "{out}"
    );
    // Every line of the result is key=value (the board's `stored seq=1 ...` included).
    assert!(
        out.contains("\nstore.result=stored\nstore.seq=1\n"),
        "{out}"
    );
    assert!(out.lines().all(|l| l.contains('=')), "{out}");
}

#[test]
fn stream_writes_csv_and_svg() {
    let (csv, svg) = (scratch("stream.csv"), scratch("stream.svg"));
    let (code, out, err) = run(&[
        "--sim",
        "stream",
        "--seconds",
        "1",
        "--divider",
        "2",
        "--csv",
        csv.to_str().unwrap(),
        "--svg",
        svg.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("\nlost=0\nbad=0\n"), "{out}");
    let rows = std::fs::read_to_string(&csv).unwrap().lines().count();
    assert!((190..=200).contains(&rows), "{rows} rows");
    assert!(std::fs::read_to_string(&svg).unwrap().starts_with("<svg"));
}

#[test]
fn sweep_prints_one_row_per_azimuth() {
    let csv = scratch("sweep.csv");
    let (code, out, err) = run(&[
        "sweep",
        "--azimuths",
        "0,90,180",
        "--seconds",
        "5",
        "--calibrate",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let rows: Vec<&str> = out.lines().filter(|l| !l.starts_with('#')).collect();
    assert_eq!(rows.len(), 4, "{out}");
    assert!(rows[0].starts_with("azimuth_deg,expected_deg_h,measured_deg_h"));
    // Calibrated: within 0.01 deg/h of the Earth-rate projection. (5 s per azimuth: the
    // closed-loop dither's amplitude wander enters the rate as its change over the window, so
    // the error falls as 1 / T: 0.04 deg/h at 1 s.)
    for row in &rows[1..] {
        let error: f64 = row.split(',').nth(3).unwrap().parse().unwrap();
        assert!(error.abs() < 0.01, "{row}");
    }
    assert_eq!(std::fs::read_to_string(&csv).unwrap().lines().count(), 4);
}

/// `serve-sim` in a child process; returns it and its first stdout line (address or path).
fn serve_sim(args: &[&str]) -> (Child, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_rlg-cal"))
        .arg("serve-sim")
        .args(args)
        .args(["--seconds", "15", "--speed", "2"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    (child, line.trim().to_owned())
}

#[test]
fn a_served_board_talks_to_a_second_process() {
    let kf = key_file();
    let (mut tcp_server, address) = serve_sim(&["--tcp", "127.0.0.1:0", "--board-key-file", &kf]);
    let (mut pty_server, path) = serve_sim(&["--pty"]);
    assert!(address.starts_with("127.0.0.1:"), "{address}");
    assert!(path.starts_with("/dev/pts/"), "{path}");
    let over_tcp = run(&["--tcp", &address, "--key-file", &kf, "set", "a", "12.5"]);
    let again = run(&["--tcp", &address, "get", "a"]);
    let over_pty = run(&["--port", &path, "--baud", "460800", "id"]);
    tcp_server.kill().unwrap();
    pty_server.kill().unwrap();
    let _ = (tcp_server.wait(), pty_server.wait());
    assert_eq!(
        (over_tcp.0, over_tcp.1.trim()),
        (0, "a=12.5"),
        "{}",
        over_tcp.2
    );
    assert_eq!((again.0, again.1.trim()), (0, "a=12.5"), "{}", again.2);
    assert_eq!(over_pty.0, 0, "{}", over_pty.2);
    assert!(over_pty.1.contains("serial=4242"), "{}", over_pty.1);
}

/// A calibration the board refuses ends the sweep with the board's reason in words, exit 1:
/// at azimuth 90 deg the axis sees no Earth rate, inside the dead band.
#[test]
fn sweep_refused_calibration_exits_1_with_the_reason() {
    let (code, out, err) = run(&[
        "sweep",
        "--calibrate",
        "--cal-azimuth",
        "90",
        "--azimuths",
        "0",
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("ERR 12 fit refused reason=1 mean rate inside the dynamic dead band"),
        "{err}"
    );
    assert!(
        !out.contains("azimuth_deg"),
        "no sweep after a refused fit: {out}"
    );
}

/// `rlg-cal record` on the simulated board: the fixed-rate output (1 kHz) for 1 s, one CSV row
/// per record with the header, no record lost, all valid once the drive has locked (the
/// simulated board boots locked), the summary counting them; a bad path fails before the run.
#[test]
fn record_writes_the_fixed_rate_output() {
    let csv = scratch("record.csv");
    let (code, out, err) = run(&[
        "--sim",
        "record",
        "--seconds",
        "1",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let field = |key: &str| -> u64 {
        out.lines()
            .find_map(|l| l.strip_prefix(key).and_then(|v| v.strip_prefix('=')))
            .unwrap_or_else(|| panic!("{key} in {out}"))
            .parse()
            .unwrap()
    };
    let (records, lost) = (field("records"), field("lost"));
    assert!((999..=1001).contains(&records), "{out}");
    assert_eq!(lost, 0);
    let written = std::fs::read_to_string(&csv).unwrap();
    let mut lines = written.lines();
    assert_eq!(
        lines.next(),
        Some("t_s,delta_angle_arcsec,valid,sequence,status")
    );
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len() as u64, records);
    assert!(
        rows.iter().all(|r| r.split(',').nth(2) == Some("1")),
        "{}",
        rows[0]
    );
    let (code, _, err) = run(&[
        "--sim",
        "record",
        "--seconds",
        "1",
        "--csv",
        "/nonexistent/dir/x.csv",
    ]);
    assert_eq!(code, 2, "{err}");
    let (code, _, err) = run(&[
        "--sim",
        "record",
        "--seconds",
        "-1",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("'--seconds <SECONDS>': -1 is outside 0 < x <= 360000 s"),
        "{err}"
    );
}

/// Every numeric argument has a range: outside it (a leading minus included where the value
/// cannot be negative, a whole number too large for the type, `inf`), exit status 2 within a
/// second, with a message naming the flag, the value and the range; a negative value where it
/// is legal is accepted.
#[test]
fn numeric_arguments_outside_their_range_are_usage_errors() {
    let csv = ["--csv", "/dev/null"];
    let cases: [(&[&str], &str, &str); 13] = [
        (
            &["--timeout-ms", "-1", "id"],
            "--timeout-ms",
            "-1 is outside 1..=600000 ms",
        ),
        (
            &["--timeout-ms", "inf", "id"],
            "--timeout-ms",
            "inf is not a finite number in 1..=600000 ms",
        ),
        (
            &["--baud", "0", "--port", "/dev/null", "id"],
            "--baud",
            "0 is outside 1200..=4000000 Bd",
        ),
        (
            &[
                "--baud",
                "99999999999999999999",
                "--port",
                "/dev/null",
                "id",
            ],
            "--baud",
            "99999999999999999999 is outside 1200..=4000000 Bd",
        ),
        (
            &["--sim", "--sim-rate", "1e300", "id"],
            "--sim-rate",
            "1e300 is outside -100000..=100000 deg/h",
        ),
        (
            &["stream", "--seconds", "-5", csv[0], csv[1]],
            "--seconds",
            "-5 is outside 0 < x <= 86400 s",
        ),
        (
            &[
                "stream",
                "--seconds",
                "1",
                csv[0],
                csv[1],
                "--divider",
                "-1",
            ],
            "--divider",
            "-1 is outside 1..=65535 cycles",
        ),
        (
            &["record", "--seconds", "360001", csv[0], csv[1]],
            "--seconds",
            "360001 is outside 0 < x <= 360000 s",
        ),
        (
            &[
                "record",
                "--seconds",
                "1",
                csv[0],
                csv[1],
                "--timer-hz",
                "0",
            ],
            "--timer-hz",
            "0 is outside 1000..=1e9 Hz",
        ),
        (
            &["calibrate", "--cycles", "0"],
            "--cycles",
            "0 is outside 1..=3600000 dither cycles",
        ),
        (
            &["sweep", "--latitude", "-91"],
            "--latitude",
            "-91 is outside -90..=90 deg",
        ),
        (
            &["sweep", "--azimuths", "0,400"],
            "--azimuths",
            "400 is outside -360..=360 deg",
        ),
        (
            &["serve-sim", "--tcp", "127.0.0.1:0", "--speed", "0"],
            "--speed",
            "0 is outside 0 < x <= 1000 simulated s per s",
        ),
    ];
    for (args, flag, says) in cases {
        let started = std::time::Instant::now();
        let (code, _, err) = run(args);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(
            err.contains("invalid value") && err.contains(flag) && err.contains(says),
            "{args:?}: {err}"
        );
        assert!(
            started.elapsed() < std::time::Duration::from_secs(1),
            "{args:?}"
        );
    }
    let kf = key_file();
    let (code, out, err) = run(&[
        "--sim",
        "--sim-rate",
        "-13.888",
        "--key-file",
        &kf,
        "get",
        "a",
    ]);
    assert_eq!((code, out.trim()), (0, "a=0"), "{err}");
}

/// No key is taken on the command line: `--key`, `unlock KEY`, `send unlock|key provision`
/// and `serve-sim --board-key` are usage errors (exit 2) that do not repeat the key; the key
/// comes from `--key-file` (or `RLG_KEY`), and `unlock` and `key-provision` use it.
#[test]
fn keys_are_never_taken_on_the_command_line() {
    const TYPED: &str = "00112233445566778899aabbccddeeff";
    for args in [
        &["--sim", "--key", TYPED, "status"][..],
        &["--sim", "unlock", TYPED],
        &["--sim", "send", "unlock", TYPED],
        &["--sim", "send", "KEY", "provision", TYPED],
        &["serve-sim", "--tcp", "127.0.0.1:0", "--board-key", TYPED],
    ] {
        let (code, out, err) = run(args);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(
            !out.contains(TYPED) && !err.contains(TYPED),
            "{args:?}: {err}"
        );
    }
    let (_, help, _) = run(&["--help"]);
    assert!(
        !help.contains("provision $KEY") && !help.contains("--key $KEY"),
        "{help}"
    );
    let kf = key_file();
    let (code, out, err) = run(&["--sim", "--key-file", &kf, "unlock"]);
    assert_eq!(
        (code, out.trim()),
        (0, "result=unlocked\nfor_s=300"),
        "{err}"
    );
    let (code, _, err) = run(&["--sim", "unlock"]);
    assert_eq!(code, 2, "no key: {err}");
    // A served board without a key: `key-provision` writes the key file's key, once.
    let (mut server, address) = serve_sim(&["--tcp", "127.0.0.1:0"]);
    let first = run(&["--tcp", &address, "--key-file", &kf, "key-provision"]);
    let second = run(&["--tcp", &address, "--key-file", &kf, "key-provision"]);
    let unlocked = run(&["--tcp", &address, "--key-file", &kf, "unlock"]);
    server.kill().unwrap();
    let _ = server.wait();
    assert_eq!(
        (first.0, first.1.trim()),
        (0, "key=provisioned"),
        "{}",
        first.2
    );
    assert_eq!(second.0, 1, "{}", second.2);
    assert!(second.2.contains("ERR 11"), "{}", second.2);
    assert!(!second.2.contains(TEST_KEY), "{}", second.2);
    assert_eq!(unlocked.0, 0, "{}", unlocked.2);
}

/// A failed unlock does not print the key: not a wrong key (stderr, and the `--json` object on
/// stdout), nor a board that does not answer.
#[test]
fn a_failed_unlock_does_not_print_the_key() {
    const WRONG: &str = "0f0e0d0c0b0a09080706050403020100";
    let wrong_file = scratch("wrong-key");
    std::fs::write(&wrong_file, WRONG).unwrap();
    let wrong_file = wrong_file.to_str().unwrap();
    let kf = key_file();
    let (mut server, address) = serve_sim(&["--tcp", "127.0.0.1:0", "--board-key-file", &kf]);
    let refused = run(&[
        "--tcp",
        &address,
        "--json",
        "--key-file",
        wrong_file,
        "set",
        "a",
        "1",
    ]);
    server.kill().unwrap();
    let _ = server.wait();
    assert_eq!(refused.0, 1, "{}", refused.2);
    assert!(refused.2.contains("ERR 15 wrong key"), "{}", refused.2);
    assert!(refused.1.contains("\"error\":15"), "{}", refused.1);
    for text in [&refused.1, &refused.2] {
        assert!(!text.contains(WRONG), "{text}");
        assert!(text.contains("unlock <key>"), "{text}");
    }
    let silent = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = silent.local_addr().unwrap().to_string();
    let (code, out, err) = run(&[
        "--tcp",
        &address,
        "--timeout-ms",
        "200",
        "--key-file",
        wrong_file,
        "set",
        "a",
        "1",
    ]);
    drop(silent);
    assert_eq!(code, 3, "{err}");
    assert!(err.contains("no answer to `unlock <key>`"), "{err}");
    assert!(!out.contains(WRONG) && !err.contains(WRONG), "{err}");
}

/// `thermal`: out-of-range flags and `--apply` without a key are usage errors (exit 2) before
/// any run; a log without a temperature span (the `--sim` board sits at 25 °C) is refused by
/// the fit with its reason (exit 1), the log written, nothing sent to the board.
#[test]
fn thermal_refuses_bad_flags_and_a_log_without_a_span() {
    for (args, says) in [
        (
            &[
                "--sim",
                "thermal",
                "--seconds",
                "0",
                "--input-rate-deg-h",
                "13.888",
            ][..],
            "0 is outside 0 < x <= 360000 s",
        ),
        (
            &[
                "--sim",
                "thermal",
                "--seconds",
                "5",
                "--input-rate-deg-h",
                "13.888",
                "--table-rate-deg-h",
                "10",
            ][..],
            "10 is outside 3600..=1e6 deg/h",
        ),
        (
            &[
                "--sim",
                "thermal",
                "--seconds",
                "5",
                "--input-rate-deg-h",
                "13.888",
                "--apply",
            ][..],
            "thermal --apply needs the unlock key",
        ),
        (
            &["--sim", "thermal", "--seconds", "5"][..],
            "--input-rate-deg-h",
        ),
    ] {
        let (code, _, err) = run(args);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
    }
    let csv = scratch("thermal.csv");
    let (code, _, err) = run(&[
        "--sim",
        "thermal",
        "--seconds",
        "3",
        "--input-rate-deg-h",
        "13.888",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("bias fit refused: temperature span under 10 C"),
        "{err}"
    );
    let log = std::fs::read_to_string(&csv).unwrap();
    assert!(log.starts_with("t_s,delta_angle_arcsec,valid,temperature_c,rate_c_min\n"));
    assert!(log.lines().count() > 2500, "{} rows", log.lines().count());
}

/// The value of `key` in key=value output lines, as a number (`None`: absent or `none`).
fn number_field(out: &str, key: &str) -> Option<f64> {
    out.lines()
        .find_map(|l| l.strip_prefix(key)?.strip_prefix('='))
        .and_then(|v| v.parse().ok())
}

/// The simulated TMP117 reads the block 0.02 °C high (hal-sim's `SENSOR_OFFSET_C`), with about
/// one LSB (1/128 °C) of noise: a result within the part's ±0.1 °C accuracy of the profile.
const SENSOR_ACCURACY_C: f64 = 0.1;

/// `--sim-temperature-profile constant:40`: the board's `thermal` answers the block's 40 °C
/// (the sensor's first results come 125 ms after boot, long before the board is handed over
/// with its drive locked); without the flag the block is at 25 °C. A bad profile is a usage
/// error naming the flag.
#[test]
fn the_sim_board_reads_the_block_on_its_temperature_profile() {
    for (profile, expected_c) in [(Some("constant:40"), 40.0), (None, 25.0)] {
        let mut args = vec!["--sim"];
        if let Some(p) = profile {
            args.extend(["--sim-temperature-profile", p]);
        }
        args.extend(["send", "thermal"]);
        let (code, out, err) = run(&args);
        assert_eq!(code, 0, "{err}");
        let temp_c = number_field(&out, "temp_c").unwrap_or_else(|| panic!("{out}"));
        // Measured: 40.0312 and 25.0312 (0.02 offset, rounded to 1/128 °C).
        assert!(
            (temp_c - expected_c).abs() < SENSOR_ACCURACY_C,
            "{profile:?}: {out}"
        );
        assert!(
            (temp_c - expected_c - 0.02).abs() < 0.04,
            "{profile:?}: {out}"
        );
    }
    let (code, _, err) = run(&[
        "--sim",
        "--sim-temperature-profile",
        "constant:200",
        "send",
        "thermal",
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains(
            "--sim-temperature-profile \"constant:200\": temperature 200 outside -55..=150 C"
        ),
        "{err}"
    );
}

/// `serve-sim --temperature-profile ramp:-50:150:120`: a second process reads the block
/// warming at 2 °C/s through `thermal`, as an integrator would. The rate is the board's slope
/// over its last 16 sensor results (2 s of board time, 1 s at --speed 2: the test polls until
/// it is known); it is 120 °C/min within 3 (the slope of 16 results of 1/128 °C, measured
/// 119.9). Later answers rise by 1 °C, at most at the ramp's 2 °C/s over the board time
/// between them: the speed times the wall clock from the first question, plus that answer's
/// age (less if the simulation falls behind on a busy machine).
#[test]
fn a_served_board_follows_its_temperature_profile() {
    const SPEED: f64 = 2.0;
    const RAMP_C_PER_S: f64 = 2.0;
    let (mut server, address) = serve_sim(&[
        "--tcp",
        "127.0.0.1:0",
        "--temperature-profile",
        "ramp:-50:150:120",
    ]);
    let thermal = || {
        let (code, out, err) = run(&["--tcp", &address, "send", "thermal"]);
        assert_eq!(code, 0, "{err}");
        out
    };
    let started = std::time::Instant::now();
    let (first, asked) = loop {
        let asked = std::time::Instant::now();
        let out = thermal();
        if number_field(&out, "rate_c_min").is_some() {
            break (out, asked);
        }
        assert!(started.elapsed().as_secs() < 10, "no rate yet: {out}");
        std::thread::sleep(std::time::Duration::from_millis(200));
    };
    let temp = |out: &str| number_field(out, "temp_c").unwrap_or_else(|| panic!("{out}"));
    let t1 = temp(&first);
    // Up to 10 s of wall clock for 1 °C more (0.25 s at full speed; the server lives 15 s).
    let (t2, wall_s) = loop {
        std::thread::sleep(std::time::Duration::from_millis(250));
        let t2 = temp(&thermal());
        let wall_s = asked.elapsed().as_secs_f64();
        if t2 - t1 >= 1.0 || wall_s > 10.0 {
            break (t2, wall_s);
        }
    };
    server.kill().unwrap();
    let _ = server.wait();
    assert!(-50.0 < t1 && t2 < 150.0, "{first}\n{t2}");
    let rate = number_field(&first, "rate_c_min").unwrap();
    assert!((rate - 120.0).abs() < 3.0, "{first}");
    // The first answer's result may be a conversion (125 ms) and a poll (50 ms) old.
    let most = RAMP_C_PER_S * (SPEED * wall_s + 0.175) + SENSOR_ACCURACY_C;
    assert!(
        t2 - t1 >= 1.0 && t2 - t1 < most,
        "{t1} -> {t2} in {wall_s} s"
    );
    let (code, _, err) = run(&[
        "serve-sim",
        "--tcp",
        "127.0.0.1:0",
        "--temperature-profile",
        "ramp:0:10",
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("--temperature-profile \"ramp:0:10\": unknown kind or wrong number of fields"),
        "{err}"
    );
}
