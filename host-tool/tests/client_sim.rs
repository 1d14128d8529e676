//! The client against the simulated board in this process: every subcommand's exchange, typed
//! errors, exactly one answer per command, calibration with progress, streaming, power cycles.

use hal_sim::flash::CalibrationFlash;
use rlg_cal::capture::DEFAULT_TIMER_HZ;
use rlg_cal::client::{Client, ClientError};
use rlg_cal::link::{Link, SimLink};
use rlg_cal::ops::{self, CalibrateOptions};
use rlg_cal::sim::{self, key_hex, test_key, SimInput};
use std::time::Duration;

fn board(rate_deg_per_h: f64, flash: CalibrationFlash, boot_count: u32) -> Client<SimLink> {
    let device = sim::boot(
        SimInput::Constant { rate_deg_per_h },
        7 + boot_count as u64,
        flash,
        boot_count,
        Some(sim::test_key()),
    )
    .unwrap();
    let mut client = Client::new(SimLink::new(device));
    // Powered up and left until its dither drive has locked, as a technician would.
    ops::wait_for_drive_lock(
        &mut client,
        ops::DRIVE_LOCK_TIMEOUT,
        Duration::from_millis(100),
    )
    .unwrap();
    client.pause(Duration::from_millis(500)).unwrap();
    client
}

/// One command, asserting that the board sent exactly one answer (nothing left over).
fn ask(client: &mut Client<SimLink>, line: &str) -> Result<String, ClientError> {
    let answer = client.command(line);
    assert_eq!(client.pending(), 0, "exactly one answer to {line:?}");
    answer.map(|a| a.text)
}

fn err_code(result: Result<String, ClientError>) -> u8 {
    let e = result.expect_err("an ERR answer");
    assert_eq!(e.exit_code(), 1, "{e}");
    e.device_code()
        .unwrap_or_else(|| panic!("not a device error: {e}"))
}

#[test]
fn reads_need_no_unlock() {
    let mut c = board(5.0, CalibrationFlash::default(), 0);
    let id = c.command("id").unwrap();
    assert_eq!(id.field("serial"), Some("4242"));
    assert_eq!(id.parse_field::<f64>("sf_arcsec").unwrap(), 1.8655);
    let status = c.command("status").unwrap();
    assert_eq!(status.field("signal"), Some("ok"));
    assert_eq!(status.field("locked"), Some("yes"));
    assert_eq!(status.field("coeffs"), Some("defaults:erased"));
    assert_eq!(ask(&mut c, "get a").unwrap(), "a=0");
    assert_eq!(ask(&mut c, "get b").unwrap(), "b=0");
    assert!(ask(&mut c, "get coeffs").unwrap().starts_with("a=0 b=0 "));
    assert!(ask(&mut c, "help").unwrap().starts_with("commands:"));
    assert_eq!(ask(&mut c, "cal status").unwrap(), "cal=idle");
    // A missing field is an error of its own kind.
    let e = id.parse_field::<u32>("nonsense").unwrap_err();
    assert!(matches!(e, ClientError::Unexpected { .. }), "{e}");
}

#[test]
fn protected_commands_need_the_key_and_answer_the_applied_value() {
    let mut c = board(5.0, CalibrationFlash::default(), 0);
    for line in [
        "set a 300",
        "comp on",
        "track on",
        "store",
        "reload",
        "defaults",
    ] {
        assert_eq!(err_code(ask(&mut c, line)), 9, "{line} while locked");
    }
    let wrong = "unlock 12341234123412341234123412341234";
    assert_eq!(err_code(ask(&mut c, "unlock 1234")), 3, "no 128-bit key");
    assert_eq!(err_code(ask(&mut c, wrong)), 15);
    match c.command(wrong).unwrap_err() {
        ClientError::Device(e) => {
            assert_eq!(e.kind, Some(firmware::protocol::ErrorCode::WrongKey));
            assert_eq!(e.text, "wrong key");
        }
        e => panic!("{e}"),
    }
    assert!(ops::unlock(&mut c, &sim::key_hex(&sim::test_key()))
        .unwrap()
        .text
        .starts_with("unlocked"));
    // Fixed-point rounding: the board answers with what it applied (Q15.16).
    assert_eq!(ask(&mut c, "set a 344.123456").unwrap(), "a=344.12344");
    assert_eq!(ask(&mut c, "set b -12.5").unwrap(), "b=-12.5");
    assert_eq!(ask(&mut c, "comp on").unwrap(), "comp=on");
    assert!(ask(&mut c, "track on").unwrap().starts_with("track=on"));
    assert!(ask(&mut c, "track off").unwrap().starts_with("track=off"));
    assert_eq!(err_code(ask(&mut c, "set a NaN")), 4);
    assert_eq!(err_code(ask(&mut c, "set a 1e9")), 5);
    assert_eq!(err_code(ask(&mut c, "frobnicate")), 1);
    assert!(ask(&mut c, "store").unwrap().starts_with("stored seq=1"));
    assert_eq!(ask(&mut c, "defaults").unwrap(), "a=0 b=0 comp=off");
    assert_eq!(
        ask(&mut c, "reload").unwrap(),
        "coeffs=flash:1 dither=stored strip=stored thermal=kept"
    );
    assert_eq!(ask(&mut c, "get a").unwrap(), "a=344.12344");
    assert_eq!(ask(&mut c, "lock").unwrap(), "locked");
    assert_eq!(err_code(ask(&mut c, "comp off")), 9);
}

/// The technician's workflow through the ops: a run with progress, the fit, accept, store;
/// after a power cycle the board has the stored coefficients.
#[test]
fn calibrate_accept_store_and_power_cycle() {
    let mut c = board(13.888, CalibrationFlash::default(), 0);
    ops::unlock(&mut c, &sim::key_hex(&sim::test_key())).unwrap();
    let mut seen: Vec<(u64, u64)> = Vec::new();
    let options = CalibrateOptions::new(3000, 100);
    let fit = ops::calibrate(&mut c, &options, &mut |done, total| {
        seen.push((done, total))
    })
    .unwrap();
    let lock_in: f64 = fit.parse_field("lock_in_deg_h").unwrap();
    assert!((lock_in / 200.0 - 1.0).abs() < 0.01, "{}", fit.text);
    assert!(
        seen.windows(2).all(|w| w[0].0 <= w[1].0),
        "progress only grows"
    );
    assert_eq!(seen.last(), Some(&(3100, 3100)));
    assert!(seen.len() >= 20, "polled through the run: {}", seen.len());
    assert!(ask(&mut c, "cal accept").unwrap().ends_with("comp=on"));
    assert!(ask(&mut c, "store").unwrap().starts_with("stored seq=1"));
    let coeffs = ask(&mut c, "get coeffs").unwrap();

    let flash = c.into_link().into_device().power_off();
    let mut c = board(13.888, flash, 1);
    assert_eq!(ask(&mut c, "get coeffs").unwrap(), coeffs);
    let status = c.command("status").unwrap();
    assert_eq!(status.field("coeffs"), Some("flash:1"));
    assert_eq!(status.field("locked"), Some("yes"));
}

#[test]
fn a_refused_fit_and_a_busy_board_are_typed_errors() {
    let mut c = board(0.5, CalibrationFlash::default(), 0);
    ops::unlock(&mut c, &sim::key_hex(&sim::test_key())).unwrap();
    ask(&mut c, "cal start 1000 10").unwrap();
    assert_eq!(err_code(ask(&mut c, "set a 1")), 10, "busy during a run");
    assert_eq!(err_code(ask(&mut c, "cal result")), 10);
    ask(&mut c, "cal abort").unwrap();
    let e = ops::calibrate(&mut c, &CalibrateOptions::new(1000, 10), &mut |_, _| {}).unwrap_err();
    assert_eq!(e.device_code(), Some(12), "{e}");
    assert!(e.to_string().contains("reason="), "{e}");
}

/// A link on which someone else aborts the run after a few polls.
struct AbortingLink {
    inner: SimLink,
    pauses: u32,
}

impl Link for AbortingLink {
    fn send(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.inner.send(bytes)
    }
    fn receive(&mut self, out: &mut Vec<u8>, timeout: Duration) -> std::io::Result<usize> {
        self.inner.receive(out, timeout)
    }
    fn elapsed(&self) -> Duration {
        self.inner.elapsed()
    }
    fn pause(&mut self, duration: Duration) {
        self.inner.pause(duration);
        self.pauses += 1;
        if self.pauses == 3 {
            let device = self.inner.device_mut();
            let crc = firmware::protocol::parse::crc16(b"cal abort");
            device.receive(format!("cal abort*{crc:04X}\n").as_bytes());
            let _ = device.take_output();
        }
    }
}

#[test]
fn a_run_aborted_meanwhile_is_a_failed_run() {
    let mut c = board(13.888, CalibrationFlash::default(), 0);
    // The unlocked user (this session) aborts: the only way a run ends early.
    ops::unlock(&mut c, &sim::key_hex(&sim::test_key())).unwrap();
    let mut c = Client::new(AbortingLink {
        inner: c.into_link(),
        pauses: 0,
    });
    let e = ops::calibrate(&mut c, &CalibrateOptions::new(3000, 0), &mut |_, _| {}).unwrap_err();
    assert!(matches!(e, ClientError::Unexpected { .. }), "{e}");
    assert!(e.to_string().contains("without completing"), "{e}");
    assert_eq!(e.exit_code(), 1);
}

/// Streaming through the client: every cycle at divider 1, no gaps, a command answered in
/// between (wrapped in 0x00), and text mode again after `stream off`.
#[test]
fn stream_capture_and_commands_while_streaming() {
    let mut c = board(10.0, CalibrationFlash::default(), 0);
    let scale = ops::rate_scale(&mut c, None).unwrap();
    assert_eq!(
        scale.timer_hz, DEFAULT_TIMER_HZ,
        "the board reports its timer"
    );
    assert!(ask(&mut c, "stream on 1").unwrap().starts_with("stream=on"));
    assert!(c.streaming());
    c.pause(Duration::from_millis(500)).unwrap();
    let status = c.command("status").unwrap();
    assert_eq!(
        status.field("signal"),
        Some("ok"),
        "answered while streaming"
    );
    assert_eq!(err_code(c.command("frobnicate").map(|a| a.text)), 1);
    let frames = c.take_frames();
    assert!((190..=200).contains(&frames.len()), "{}", frames.len());
    assert!(ask(&mut c, "stream off").unwrap().starts_with("stream=off"));
    assert!(!c.streaming());
    assert_eq!(ask(&mut c, "get a").unwrap(), "a=0");

    let capture = ops::stream(&mut c, 3, Duration::from_secs(2), &mut |_| {}).unwrap();
    assert!(!c.streaming());
    assert_eq!((capture.lost(), capture.bad_frames), (0, 0));
    let n = capture.records.len();
    assert!((255..=262).contains(&n), "2 s at 389/3 Hz: {n}");
    let (compensated, raw) = capture.mean_rates(&scale);
    assert!((raw - 10.0).abs() < 1.0, "{raw}");
    assert_eq!(compensated, raw, "compensation is off");
    let seconds = capture.per_second(&scale);
    assert_eq!(seconds.len(), 2);
    assert!(seconds.iter().all(|s| (s.raw_deg_per_h - 10.0).abs() < 1.5));
}

/// A store with the worst-case sector erase (2 s, the F405 datasheet's maximum) answers after
/// the client's default 2 s timeout would have run out: the client waits for `store` as long
/// as a store can stall (plus its timeout), and still times out other commands at 2 s.
#[test]
fn a_store_with_a_worst_case_erase_is_waited_for() {
    use hal_sim::flash::FlashTiming;
    let mut flash = CalibrationFlash::default().with_timing(FlashTiming {
        sector_erase_s: 2.0,
        ..FlashTiming::default()
    });
    // Sector 0 looks full (its last byte programmed): the store erases blank sector 1 first.
    flash.corrupt(128 * 1024 - 1, 0xFF);
    let mut c = board(5.0, flash, 0);
    ops::unlock(&mut c, &sim::key_hex(&sim::test_key())).unwrap();
    let before = c.elapsed();
    let stored = ask(&mut c, "store").expect("store answered");
    assert!(stored.starts_with("stored seq=1"), "{stored}");
    let waited = c.elapsed() - before;
    assert!(waited > Duration::from_millis(2000), "{waited:?}");
    assert_eq!(
        rlg_cal::client::answer_timeout("get a", Duration::from_secs(2)),
        Duration::from_secs(2)
    );
}

/// Wrong keys used the free attempts: `ops::unlock` with the right key is refused (ERR 14,
/// outside the window), waits the time the board names and is in at the next window, within
/// the window period (10 s) plus the exchanges.
#[test]
fn unlock_waits_for_the_next_window_and_gets_in() {
    let mut c = board(5.0, CalibrationFlash::default(), 0);
    for _ in 0..3 {
        let wrong = ops::unlock(&mut c, &"12".repeat(16));
        assert_eq!(wrong.unwrap_err().device_code(), Some(15));
    }
    let started = c.elapsed();
    let answer = ops::unlock(&mut c, &key_hex(&test_key())).unwrap();
    let took = c.elapsed() - started;
    assert_eq!(answer.text, "unlocked for_s=300");
    assert!(
        took > Duration::from_secs(5) && took <= Duration::from_millis(10_100),
        "{took:?}"
    );
}
