//! The simulated board's serial link around a flash stall: every answer comes when its stall
//! is over and in order, and a new session (a served board's new TCP client) inherits nothing
//! of the previous one, not even bytes or answers held during a stall.

mod device_support;

use device_support::{boot_with_key, exchange, field, KEY};
use embedded_storage::nor_flash::NorFlash;
use firmware::protocol::parse::crc16;
use hal_sim::device::SimDevice;
use hal_sim::flash::CalibrationFlash;
use hal_sim::params::GyroParams;

/// A line as the host tool sends it, with its CRC suffix.
fn with_crc(text: &str) -> Vec<u8> {
    format!("{text}*{:04X}\n", crc16(text.as_bytes())).into_bytes()
}

/// Runs the board in 20 ms steps (serve-sim's largest step) until `lines` answer lines came
/// or `limit_s` passed; the text received and the simulated seconds it took.
fn collect(dev: &mut SimDevice, lines: usize, limit_s: f64) -> (String, f64) {
    let start_s = dev.time_s();
    let mut out = dev.take_output();
    while out.windows(2).filter(|w| w == b"\r\n").count() < lines
        && dev.time_s() - start_s < limit_s
    {
        dev.run_for(0.02);
        out.extend(dev.take_output());
    }
    (String::from_utf8(out).unwrap(), dev.time_s() - start_s)
}

/// A board whose sector 0 is full of damage, so that its first store erases sector 1 (a 1 s
/// stall in the flash model).
fn board_whose_first_store_erases() -> SimDevice {
    let mut flash = CalibrationFlash::default();
    flash.write(0, &vec![0u8; 128 * 1024]).unwrap();
    let mut dev = boot_with_key(GyroParams::default(), 13.888, flash, 0);
    dev.run_for(1.0);
    dev
}

/// Twelve clients in turn, each `unlock` then `store`, as `rlg-cal store` does against a
/// served board: every store is answered once, within its stall plus one 20 ms step (no
/// erase here: a few hundred microseconds), in order, with consecutive record numbers. (Each
/// stall was booked as at least 1 ms and the time a step overshot it was carried into the
/// next as a negative stall, which swallowed the fifth answer until the next store.)
#[test]
fn every_store_is_answered_when_its_stall_is_over() {
    let mut dev = boot_with_key(
        GyroParams::default(),
        13.888,
        CalibrationFlash::default(),
        0,
    );
    dev.run_for(1.0);
    for seq in 1..=12 {
        dev.new_session();
        dev.receive(&with_crc(&format!("unlock {KEY}")));
        let (unlocked, _) = collect(&mut dev, 1, 0.1);
        assert!(unlocked.starts_with("OK unlocked"), "{unlocked}");
        dev.receive(&with_crc("store"));
        let (stored, took_s) = collect(&mut dev, 1, 3.0);
        let lines: Vec<&str> = stored.lines().collect();
        assert_eq!(lines.len(), 1, "store {seq}: {stored:?}");
        assert!(
            lines[0].starts_with(&format!("OK stored seq={seq} ")),
            "store {seq}: {stored:?}"
        );
        assert!(took_s <= 0.021, "store {seq} answered after {took_s:.3} s");
    }
}

/// Client A unlocks, sends a store that erases (1 s) and, during the stall, half a line
/// (`set a 1`); client B connects during the stall and sends `3.5` and `status`. B gets no
/// answer of A's, A's half line does not join B's bytes into `set a 13.5`, and the board stays
/// locked with `a` unchanged: B's `3.5` is an unknown command and `status` says `locked=yes`.
#[test]
fn a_new_session_during_a_stall_inherits_no_held_bytes_or_answers() {
    let mut dev = board_whose_first_store_erases();
    dev.receive(&with_crc(&format!("unlock {KEY}")));
    let (unlocked, _) = collect(&mut dev, 1, 0.1);
    assert!(unlocked.starts_with("OK unlocked"), "{unlocked}");
    dev.receive(&with_crc("store"));
    dev.run_for(0.1);
    dev.receive(b"get a\nset a 1");
    assert!(dev.take_output().is_empty(), "the store stalls the board");
    dev.new_session();
    dev.receive(b"3.5\nstatus\nget a\n");
    let (text, _) = collect(&mut dev, 3, 3.0);
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 3, "B's three answers only: {text:?}");
    assert!(lines[0].starts_with("ERR 1 "), "`3.5` alone: {text:?}");
    assert!(
        lines[1].starts_with("OK ") && lines[1].contains("locked=yes"),
        "{text:?}"
    );
    assert_eq!(lines[2], "OK a=0", "{text:?}");
    assert!(!text.contains("stored"), "A's answer went to B: {text:?}");
    // The store itself went through: it is the board's, not the session's.
    let status = exchange(&mut dev, b"status\n");
    assert_eq!(field(&status, "coeffs"), "flash:1", "{status}");
}
