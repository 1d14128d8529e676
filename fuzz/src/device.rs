//! The `device` target: arbitrary serial bytes to hal-sim's simulated board (`SimDevice`: the
//! firmware's service against the simulated gyro and the NOR flash model), with simulated time
//! passing, new sessions (a served board's new TCP client) and power cycles. Stores stall the
//! board for their flash time: bytes and answers wait for the stall's end, and a new session
//! during a stall drops the previous client's.
//!
//! Checked, besides no panic:
//! - every answer well formed, every frame decodes;
//! - within a session, never more answers than the lines sent in it (nothing of a previous
//!   session's reaches it), and, the board run on for up to 2.1 s (longer than a store's
//!   stall), exactly one answer per non-empty line of the last session (none held back).
//!
//! Event bytes ([`super::events`]): `TICK` runs the board 0.3 s, `CYCLES` 0.1 s, `OUTPUTS`
//! 20 ms;
//! `NEW_SESSION`; `RESET` powers the board off and on (the flash kept); `TICK_SHORT` sends a
//! checksummed `store` (the stall path); `FAIL_STORE` arms a power cut 40 bytes into the next
//! flash programming; `BLANK_OTP` first: the board has no key. The simulated time one input's
//! events run is bounded (3 s): the simulation dominates a run's cost.

use firmware::protocol::execute::Identity;
use firmware::protocol::key::Key;
use firmware::protocol::output_frame::decode_output_frame;
use firmware::protocol::parse::crc16;
use firmware::protocol::stream::decode_frame;
use firmware::protocol::thermal_frame::decode_thermal_frame;
use hal_sim::device::{SimDevice, SIM_IDENTITY};
use hal_sim::flash::{CalibrationFlash, PowerCut};
use hal_sim::input::InputProfile;
use hal_sim::params::GyroParams;

use super::answers::{check_answer, split_output, LineCounter};
use super::events::{BLANK_OTP, CYCLES, FAIL_STORE, NEW_SESSION, OUTPUTS, RESET, TICK, TICK_SHORT};

/// The simulated board's key in this target: the seeds type it as
/// `3a7c5e91b2d4f60819e3c5a7b9d1f2e4`.
pub const KEY: &str = "3a7c5e91b2d4f60819e3c5a7b9d1f2e4";

/// Simulated seconds one input's events may run the board.
const MAX_SIM_S: f64 = 3.0;
/// The longest a line's answer may wait: a store's stall (`STORE_STALL_MAX_MS`) and a step.
const ANSWER_WAIT_S: f64 = 2.1;

fn boot(flash: CalibrationFlash, key: Option<Key>, boot_count: u32) -> SimDevice {
    let identity = Identity {
        key,
        ..SIM_IDENTITY
    };
    SimDevice::boot(
        GyroParams::default(),
        InputProfile::constant(13.888),
        identity,
        flash,
        boot_count,
    )
    .expect("the simulated board boots")
}

/// The session's bookkeeping.
struct Session {
    lines: LineCounter,
    answers: usize,
}

impl Session {
    fn new() -> Self {
        Self {
            lines: LineCounter::default(),
            answers: 0,
        }
    }

    /// Takes the board's output, checks it and counts the answers.
    fn take(&mut self, dev: &mut SimDevice) {
        let out = split_output(&dev.take_output());
        for answer in &out.answers {
            check_answer(answer, None);
        }
        for frame in &out.frames {
            assert!(
                decode_frame(frame).is_ok()
                    || decode_output_frame(frame).is_ok()
                    || decode_thermal_frame(frame).is_ok(),
                "a bad frame: {frame:?}"
            );
        }
        self.answers += out.answers.len();
        assert!(
            self.answers <= self.lines.lines,
            "{} answers to {} lines of this session",
            self.answers,
            self.lines.lines
        );
    }

    fn send(&mut self, dev: &mut SimDevice, bytes: &[u8]) {
        for &b in bytes {
            self.lines.push(b);
        }
        dev.receive(bytes);
    }
}

/// Runs the simulated board over `data` (panics on a broken promise).
pub fn check(data: &[u8]) {
    let (key, data) = match data.split_first() {
        Some((&BLANK_OTP, rest)) => (None, rest),
        _ => (Key::parse_hex(KEY), data),
    };
    let mut dev = boot(CalibrationFlash::default(), key, 0);
    let mut boots = 0;
    let mut session = Session::new();
    let start_s = dev.time_s();
    let mut pending: Vec<u8> = Vec::new();
    for &byte in data {
        let run_s = match byte {
            TICK => 0.3,
            CYCLES => 0.1,
            OUTPUTS => 0.02,
            NEW_SESSION | RESET | TICK_SHORT | FAIL_STORE => 0.0,
            _ => {
                pending.push(byte);
                continue;
            }
        };
        session.send(&mut dev, &std::mem::take(&mut pending));
        match byte {
            NEW_SESSION => {
                session.take(&mut dev);
                dev.new_session();
                session = Session::new();
            }
            RESET => {
                boots += 1;
                let flash = dev.power_off();
                dev = boot(flash, key, boots);
                session = Session::new();
            }
            TICK_SHORT => {
                let line = format!("store*{:04X}\n", crc16(b"store"));
                session.send(&mut dev, line.as_bytes());
            }
            FAIL_STORE => dev.flash_mut().arm_power_cut(PowerCut::AfterBytes(40)),
            _ => {}
        }
        if run_s > 0.0 && dev.time_s() - start_s < MAX_SIM_S {
            dev.run_for(run_s);
        }
        session.take(&mut dev);
    }
    session.send(&mut dev, &pending);
    let waited_from_s = dev.time_s();
    session.take(&mut dev);
    while session.answers < session.lines.lines && dev.time_s() - waited_from_s < ANSWER_WAIT_S {
        dev.run_for(0.05);
        session.take(&mut dev);
    }
    assert_eq!(
        session.answers, session.lines.lines,
        "one answer per non-empty line of the last session"
    );
}
