//! The tool as a gyro engineer uses it on a served board (`rlg-cal serve-sim --tcp
//! 127.0.0.1:0`, real time, in a child process): Ctrl-C loses nothing, every precondition is
//! checked before the long run, the connection and the key come from anywhere on the line or
//! the environment, the `--sim` board keeps its state in a file, results are `key=value` or
//! JSON.

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, ChildStderr, ChildStdout, Command, Output, Stdio};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_rlg-cal");

fn rlg_cal(args: &[&str], env: &[(&str, &str)]) -> Command {
    let mut c = Command::new(BIN);
    c.args(args).stdin(Stdio::null());
    for var in [
        "RLG_PORT",
        "RLG_TCP",
        "RLG_BAUD",
        "RLG_KEY",
        "RLG_SIM_STATE",
    ] {
        c.env_remove(var);
    }
    c.envs(env.iter().copied());
    c
}

/// (exit code, stdout, stderr, wall time)
fn run(args: &[&str], env: &[(&str, &str)]) -> (i32, String, String, Duration) {
    let started = Instant::now();
    let out: Output = rlg_cal(args, env).output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
        started.elapsed(),
    )
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rlg-cal-long-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// A served board (real time, at most 30 s) and its address; killed when dropped.
struct Served {
    child: Child,
    address: String,
    banner: String,
    // Held open: the server writes to them while it runs.
    _pipes: (BufReader<ChildStdout>, BufReader<ChildStderr>),
}

impl Drop for Served {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The served boards' key (a test fixture: the simulated board has no key of its own).
const KEY: &str = "3a7c5e91b2d4f60819e3c5a7b9d1f2e4";

fn served() -> Served {
    let mut child = rlg_cal(
        &["serve-sim", "--tcp", "127.0.0.1:0", "--seconds", "30"],
        &[("RLG_SIM_BOARD_KEY", KEY)],
    )
    .stdout(Stdio::piped())
    .stderr(Stdio::piped())
    .spawn()
    .unwrap();
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let mut stderr = BufReader::new(child.stderr.take().unwrap());
    let mut address = String::new();
    stdout.read_line(&mut address).unwrap();
    let mut banner = String::new();
    stderr.read_line(&mut banner).unwrap();
    Served {
        child,
        address: address.trim().to_owned(),
        banner,
        _pipes: (stdout, stderr),
    }
}

/// Takes `child`'s stderr and reads it until a line containing `announcement` (the long
/// work under way); the rest stays to be read.
fn stderr_after(child: &mut Child, announcement: &str) -> BufReader<ChildStderr> {
    let mut stderr = BufReader::new(child.stderr.take().unwrap());
    let mut line = String::new();
    while !line.contains(announcement) {
        line.clear();
        assert!(
            stderr.read_line(&mut line).unwrap() > 0,
            "ended before {announcement:?}"
        );
    }
    stderr
}

fn interrupt(child: &Child) {
    // SAFETY: a signal to our own child process.
    assert_eq!(
        unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) },
        0
    );
}

/// Ctrl-C 3 s into an 8 s stream: exit 130, the CSV holds every frame received (as many rows
/// as the summary's `frames=`, consecutive sequence numbers, the last row complete), at the
/// board's 389 cycles per second (the rows' own time stamps: within 1 %), the SVG drawn.
#[test]
fn sigint_keeps_every_streamed_frame() {
    let board = served();
    let (csv, svg) = (scratch("int.csv"), scratch("int.svg"));
    let mut child = rlg_cal(
        &[
            "--tcp",
            &board.address,
            "stream",
            "--seconds",
            "8",
            "--csv",
            csv.to_str().unwrap(),
            "--svg",
            svg.to_str().unwrap(),
        ],
        &[],
    )
    .stdout(Stdio::piped())
    .stderr(Stdio::piped())
    .spawn()
    .unwrap();
    // 3 s after the stream starts (its announcement on stderr), Ctrl-C.
    let mut stderr = stderr_after(&mut child, "streaming every");
    std::thread::sleep(Duration::from_secs(3));
    interrupt(&child);
    let mut stderr_rest = String::new();
    std::io::Read::read_to_string(&mut stderr, &mut stderr_rest).unwrap();
    let out = child.wait_with_output().unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), stderr_rest);
    assert_eq!(out.status.code(), Some(130), "{stderr}");
    assert!(stdout.contains("interrupted=yes"), "{stdout}");
    let frames: usize = stdout
        .lines()
        .find_map(|l| l.strip_prefix("frames="))
        .expect("summary")
        .parse()
        .unwrap();
    let text = std::fs::read_to_string(&csv).unwrap();
    assert!(text.ends_with('\n'), "last row complete");
    let rows: Vec<Vec<&str>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(rows.len(), frames, "every frame received is in the CSV");
    // About 3 s of streaming at 389 frames/s (3.4 s with the signal's latency); at least 1.5 s
    // of it even on a loaded machine.
    assert!((580..=1330).contains(&frames), "{frames} frames");
    assert!(
        rows.iter().all(|r| r.len() == 10),
        "every row has its 10 fields"
    );
    let seq: Vec<u32> = rows.iter().map(|r| r[0].parse().unwrap()).collect();
    assert!(seq.windows(2).all(|w| w[1] == w[0] + 1), "no frame missing");
    let last_t: f64 = rows.last().unwrap()[1].parse().unwrap();
    let per_s = (rows.len() - 1) as f64 / last_t;
    assert!((per_s - 389.0).abs() < 3.9, "{per_s} rows per second");
    assert!(std::fs::read_to_string(&svg).unwrap().starts_with("<svg"));
}

/// Ctrl-C during `calibrate`: exit 130, and the board is not left calibrating (`cal abort`
/// was sent: `cal status` answers idle).
#[test]
fn sigint_during_calibrate_aborts_the_run_on_the_board() {
    let board = served();
    let mut child = rlg_cal(
        &["--tcp", &board.address, "calibrate", "--cycles", "100000"],
        &[("RLG_KEY", KEY)],
    )
    .stdout(Stdio::piped())
    .stderr(Stdio::piped())
    .spawn()
    .unwrap();
    // Ctrl-C once the run is under way on the board (its announcement on stderr; a second
    // client cannot look: a new TCP connection takes the served board over).
    let mut stderr = stderr_after(&mut child, "the calibration runs on the board");
    interrupt(&child);
    let mut stderr_rest = String::new();
    std::io::Read::read_to_string(&mut stderr, &mut stderr_rest).unwrap();
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(130), "{stderr_rest}");
    assert!(stderr_rest.contains("cal abort"), "{stderr_rest}");
    let (code, status, err, _) = run(&["--tcp", &board.address, "send", "cal", "status"], &[]);
    assert_eq!((code, status.trim()), (0, "cal=idle"), "{err}");
}

/// Errors before the long run, each within a second: an output file that cannot be created
/// and a missing key are usage errors (2), no board is a connection error (3).
#[test]
fn preconditions_fail_before_the_run() {
    let board = served();
    let a = board.address.as_str();
    for (args, expected) in [
        (
            &[
                "--tcp",
                a,
                "stream",
                "--seconds",
                "60",
                "--csv",
                "/nonexistent/dir/x.csv",
            ][..],
            2,
        ),
        (
            &[
                "--tcp",
                a,
                "stream",
                "--seconds",
                "60",
                "--csv",
                "/dev/null",
                "--svg",
                "/nonexistent/x.svg",
            ][..],
            2,
        ),
        (&["--tcp", a, "calibrate", "--accept"][..], 2),
        (
            &[
                "--tcp",
                a,
                "calibrate",
                "--accept",
                "--key-file",
                "/nonexistent/key",
            ][..],
            2,
        ),
        (&["sweep", "--svg", "/nonexistent/x.svg"][..], 2),
        (
            &[
                "--tcp",
                "127.0.0.1:1",
                "stream",
                "--seconds",
                "60",
                "--csv",
                "/dev/null",
            ][..],
            3,
        ),
    ] {
        let (code, _, err, took) = run(args, &[]);
        assert_eq!(code, expected, "{args:?}: {err}");
        assert!(took < Duration::from_secs(1), "{args:?}: {took:?}");
    }
}

/// Connection options after the subcommand, from the environment, and the key from a file or
/// the environment; `serve-sim --tcp 127.0.0.1:0` prints its address and a sentence with units.
#[test]
fn one_way_to_connect() {
    let board = served();
    let a = board.address.as_str();
    assert!(a.starts_with("127.0.0.1:"), "{a}");
    assert!(
        board.banner.contains("13.888 deg/h") && !board.banner.contains("Constant {"),
        "{}",
        board.banner
    );
    let (code, out, err, _) = run(&["status", "--tcp", a], &[]);
    assert_eq!(code, 0, "{err}");
    assert!(out.starts_with("signal="), "{out}");
    let (code, out, err, _) = run(&["id"], &[("RLG_TCP", a)]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("serial=4242"), "{out}");
    let key = scratch("key.txt");
    std::fs::write(&key, format!("{KEY}\n")).unwrap();
    let (code, out, err, _) = run(
        &["set", "a", "12.5", "--key-file", key.to_str().unwrap()],
        &[("RLG_TCP", a)],
    );
    assert_eq!((code, out.trim()), (0, "a=12.5"), "{err}");
    let (code, out, err, _) = run(&["set", "b", "-3.25"], &[("RLG_TCP", a), ("RLG_KEY", KEY)]);
    assert_eq!((code, out.trim()), (0, "b=-3.25"), "{err}");
    // The command line wins over the environment.
    let (code, _, err, _) = run(&["--tcp", a, "id"], &[("RLG_PORT", "/dev/nonexistent")]);
    assert_eq!(code, 0, "{err}");
    // No connection anywhere: usage.
    let (code, _, _, _) = run(&["id"], &[]);
    assert_eq!(code, 2);
}

/// `--sim` with a state file behaves as one board over several calls: `store` in one call and
/// `reload` in the next find the record; a setting made in one call is in force in the next.
#[test]
fn the_sim_board_keeps_its_state_file() {
    let state = scratch("board.state");
    let _ = std::fs::remove_file(&state);
    let s = state.to_str().unwrap();
    let sim = |args: &[&str]| {
        let mut all = vec!["--sim", "--sim-state", s];
        all.extend_from_slice(args);
        run(&all, &[("RLG_KEY", KEY)])
    };
    let (code, out, err, _) = sim(&["set", "a", "12.5"]);
    assert_eq!((code, out.trim()), (0, "a=12.5"), "{err}");
    let (code, out, err, _) = sim(&["store"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("result=stored\nseq=1"), "{out}");
    let (code, out, err, _) = sim(&["set", "a", "7"]);
    assert_eq!((code, out.trim()), (0, "a=7"), "{err}");
    let (code, out, err, _) = sim(&["get", "a"]);
    assert_eq!((code, out.trim()), (0, "a=7"), "the setting lasts: {err}");
    let (code, out, err, _) = sim(&["reload"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("coeffs=flash:1"),
        "the stored record is found: {out}"
    );
    let (code, out, err, _) = run(&["--sim", "get", "a"], &[("RLG_SIM_STATE", s)]);
    assert_eq!((code, out.trim()), (0, "a=12.5"), "{err}");
    // Without a state file the board forgets.
    let (_, out, _, _) = run(&["--sim", "get", "a"], &[]);
    assert_eq!(out.trim(), "a=0");
    let (_, help, _, _) = run(&["--help"], &[]);
    assert!(
        help.contains("--sim-state") && help.contains("What lasts"),
        "{help}"
    );
}

/// `--json`: one JSON object per command, numbers as numbers; every default result line is
/// `key=value`.
#[test]
fn results_for_scripts() {
    let (code, out, err, _) = run(&["--sim", "--json", "store"], &[("RLG_KEY", KEY)]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(out.lines().count(), 1, "{out}");
    let line = out.trim();
    assert!(line.starts_with("{\"") && line.ends_with('}'), "{line}");
    assert!(
        line.contains("\"result\":\"stored\"") && line.contains("\"seq\":1"),
        "{line}"
    );
    let (code, out, _, _) = run(&["--sim", "--json", "set", "a", "1"], &[]);
    assert_eq!(code, 1);
    assert_eq!(
        out.trim(),
        r#"{"command":"set a 1","error":9,"error_text":"locked (unlock first)"}"#
    );
    let (code, out, err, _) = run(&["--sim", "status"], &[]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.lines()
            .all(|l| l.split_once('=').is_some_and(|(k, _)| !k.is_empty())),
        "{out}"
    );
}

/// Ctrl-C during `rlg-cal sweep`: the azimuths done are kept (printed and in the CSV, the same
/// rows), exit 130.
#[test]
fn sigint_during_a_sweep_keeps_the_azimuths_done() {
    let csv = scratch("sweep-int.csv");
    let azimuths: Vec<String> = (0..36).map(|i| (i * 10).to_string()).collect();
    let azimuths = azimuths.join(",");
    let mut child = rlg_cal(
        &[
            "sweep",
            "--azimuths",
            &azimuths,
            "--csv",
            csv.to_str().unwrap(),
        ],
        &[],
    )
    .stdout(Stdio::piped())
    .stderr(Stdio::piped())
    .spawn()
    .unwrap();
    // The first azimuth measured (a progress line on stderr), then Ctrl-C.
    let mut stderr = stderr_after(&mut child, "measured");
    interrupt(&child);
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut stderr, &mut rest).unwrap();
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(130), "{rest}");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let printed = stdout.lines().filter(|l| !l.starts_with('#')).count() - 1;
    let written = std::fs::read_to_string(&csv).unwrap().lines().count() - 1;
    assert!((1..36).contains(&printed), "{stdout}");
    assert_eq!(printed, written);
}

/// A port that accepts the connection and never answers: `stream` and `calibrate` fail as a
/// connection error (3) within a second (plus start-up), before the run, although the answer
/// timeout is 2 s.
#[test]
fn a_silent_board_fails_before_the_run() {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap().to_string();
    let accepting = std::thread::spawn(move || {
        // Hold the connections open, answer nothing.
        let held: Vec<_> = listener.incoming().take(2).collect();
        std::thread::sleep(Duration::from_secs(3));
        drop(held);
    });
    for args in [
        &[
            "--tcp",
            address.as_str(),
            "stream",
            "--seconds",
            "60",
            "--csv",
            "/dev/null",
        ][..],
        &["--tcp", address.as_str(), "calibrate"][..],
    ] {
        let (code, _, err, took) = run(args, &[("RLG_KEY", KEY)]);
        assert_eq!(code, 3, "{args:?}: {err}");
        assert!(err.contains("no answer to `id`"), "{err}");
        assert!(took < Duration::from_millis(1500), "{args:?}: {took:?}");
    }
    accepting.join().unwrap();
}

/// `serve-sim --tcp 127.0.0.1:0` with nothing else starts and prints its address; Ctrl-C
/// stops it with exit status 130.
#[test]
fn serve_sim_starts_with_an_address_alone_and_stops_on_ctrl_c() {
    let mut child = rlg_cal(&["serve-sim", "--tcp", "127.0.0.1:0"], &[])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut address = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut address)
        .unwrap();
    assert!(address.trim().starts_with("127.0.0.1:"), "{address}");
    interrupt(&child);
    assert_eq!(child.wait().unwrap().code(), Some(130));
}

/// A state file at the last boot count: the next call boots and saves it again, the count
/// saturated (it never wraps, and adding one does not panic).
#[test]
fn a_state_file_at_the_last_boot_count_does_not_overflow() {
    let state = scratch("last-boot.state");
    let _ = std::fs::remove_file(&state);
    let s = state.to_str().unwrap();
    let (code, _, err, _) = run(&["--sim", "--sim-state", s, "id"], &[]);
    assert_eq!(code, 0, "{err}");
    let bytes = std::fs::read(&state).unwrap();
    let text = String::from_utf8_lossy(&bytes);
    assert!(text.contains("\nboot_count=1\n"), "{text}");
    let header_end = bytes.windows(2).position(|w| w == b"\n\n").unwrap();
    let header = String::from_utf8(bytes[..header_end].to_vec()).unwrap();
    let mut edited = header
        .replace("boot_count=1", &format!("boot_count={}", u32::MAX))
        .into_bytes();
    edited.extend_from_slice(&bytes[header_end..]);
    std::fs::write(&state, edited).unwrap();
    let (code, _, err, _) = run(&["--sim", "--sim-state", s, "id"], &[]);
    assert_eq!(code, 0, "{err}");
    let text = String::from_utf8_lossy(&std::fs::read(&state).unwrap()).into_owned();
    assert!(
        text.contains(&format!("\nboot_count={}\n", u32::MAX)),
        "{text}"
    );
    std::fs::remove_file(&state).unwrap();
}
