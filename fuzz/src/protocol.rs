//! The `protocol` target: arbitrary serial bytes through the firmware's own line assembler,
//! checksum, parser and executor, against a small in-memory device, checking the promises of
//! the protocol on every answer:
//!
//! - no panic, whatever the bytes;
//! - exactly one answer per non-empty line (counted independently of the assembler), none for
//!   empty lines or an unfinished last line;
//! - every answer well formed: printable ASCII, at most `MAX_RESPONSE` bytes, ending in `\r\n`,
//!   `OK` or `ERR <code> <text>` with a known code and its text, a valid CRC suffix exactly when
//!   the request carried a valid one;
//! - after an `ERR`, nothing observable changed: settings, stored records, streaming, the
//!   lock state and the answers to `status`, `cal status`, `get coeffs` and `thermal model`
//!   (the thermal model in force and its switch), and the pending
//!   confirmation (what `yes` would do: every line but the echo drops it, so after an `ERR`
//!   nothing is pending; after `ERR 18` exactly the echoed command is). Two answers are exempt
//!   by design: `ERR 15` (a wrong key locks the board, asserted instead) and `ERR 12` (`cal
//!   result` reporting a refused fit: solving is a one-way step of the session);
//! - a streamed record survives `encode_frame`/`decode_frame` unchanged.
//!
//! Event bytes ([`super::events`]): [`TICK`] and [`TICK_SHORT`] (time passes: unlock
//! timeouts, the unlock windows), [`CYCLES`] (400 dither cycles reach the executor:
//! calibration runs, streaming, staged settings taking effect), [`FAIL_STORE`] (the next flash
//! store or OTP write fails), [`NEW_SESSION`] (the executor's new session and an empty line:
//! checked locked, not streaming, nothing pending) and, as the first byte only, [`BLANK_OTP`]
//! (the board boots unprovisioned: `key provision` writes its key, once). Every other byte
//! goes to the assembler, and 7 ms pass per byte.

use firmware::calibration::validation::AcceptanceLimits;
use firmware::dither::{CommandError, DitherConfig, DitherController, DitherStatus};
use firmware::profile::BoardProfile;
use firmware::protocol::endpoint;
use firmware::protocol::execute::{DeviceLink, DeviceStatus, Executor, Identity};
use firmware::protocol::key::Key;
use firmware::protocol::line::{LineAssembler, LineEvent};
use firmware::protocol::link::KeyWriteError;
use firmware::protocol::parse::{parse, strip_checksum, Command};
use firmware::protocol::stream::{decode_frame, encode_frame, MAX_FRAME};

use super::answers::{check_answer, has_valid_crc, LineCounter};
use firmware::signal::compensation::CompensationSettings;
use firmware::signal::lockin::CycleRecord;
use firmware::signal::lockin::LockinTerms;
use firmware::signal::lockin::{CycleFlags, CycleOutput};
use firmware::storage::{
    CalibrationRecord, DefaultsReason, DitherSetpoints, LoadOutcome, LoadReport, StoreError,
    Stored, StripCoefficients,
};
use firmware::thermal::model::ThermalModel;
use firmware::thermal::state::ThermalState;
use firmware::units::{PhaseDelta, TotalPhase};

pub use super::events::{BLANK_OTP, CYCLES, FAIL_STORE, NEW_SESSION, TICK, TICK_SHORT};

/// The identity the harness answers `id` with; its key, as the seeds type it, is
/// `f0e1d2c3b4a5968778695a4b3c2d1e0f`.
pub const IDENTITY: Identity = Identity {
    firmware_version: "0.0.0-fuzz",
    build: "fuzz",
    board: "memory",
    serial_number: 7,
    key: Some(Key::from_bytes([
        0xf0, 0xe1, 0xd2, 0xc3, 0xb4, 0xa5, 0x96, 0x87, 0x78, 0x69, 0x5a, 0x4b, 0x3c, 0x2d, 0x1e,
        0x0f,
    ])),
    scale_factor_arcsec: 1.8655,
    capture_timer_hz: 84_000_000,
};

/// The in-memory device: settings staged and applied at the next cycle, a flash log, and the
/// firmware's own dither controller (the F405 profile's settings; no ticks, so its state stays
/// where the commands put it, and its range checks are the real ones).
#[derive(Clone, Debug)]
struct MemDevice {
    now_ms: u64,
    active: CompensationSettings,
    staged: Option<CompensationSettings>,
    stored: Vec<CalibrationRecord>,
    fail_next_store: bool,
    dither_config: DitherConfig,
    dither: DitherController,
    strip: Option<StripCoefficients>,
    /// The OTP key words: `None` blank (`key provision` writes them once).
    otp_key: Option<Key>,
    /// The thermal model in force and its switch (no sensor).
    thermal: ThermalState,
}

impl DeviceLink for MemDevice {
    type FlashError = ();

    fn now_ms(&self) -> u64 {
        self.now_ms
    }

    fn status(&self) -> DeviceStatus {
        DeviceStatus {
            signal_ok: true,
            dither_hz: 389.0,
            dither_amplitude_rad: 9.5,
            rate_deg_per_h: 13.9,
            ..DeviceStatus::default()
        }
    }

    fn active_settings(&mut self) -> CompensationSettings {
        self.staged.unwrap_or(self.active)
    }

    fn stage_settings(&mut self, settings: CompensationSettings) {
        self.staged = Some(settings);
    }

    fn store(&mut self, record: &CalibrationRecord) -> Result<Stored, StoreError<()>> {
        if core::mem::take(&mut self.fail_next_store) {
            return Err(StoreError::Flash(()));
        }
        self.stored.push(*record);
        Ok(Stored {
            sequence: self.stored.len() as u32,
            erased: false,
        })
    }

    fn load(&mut self) -> (CalibrationRecord, LoadReport) {
        let outcome = match self.stored.len() {
            0 => LoadOutcome::Defaults {
                reason: DefaultsReason::Erased,
            },
            n => LoadOutcome::Loaded { sequence: n as u32 },
        };
        let record = self
            .stored
            .last()
            .copied()
            .unwrap_or(CalibrationRecord::DEFAULTS);
        (record, report(outcome))
    }

    /// The drive is locked whenever it is enabled (no ticks here to lock it).
    fn dither_status(&mut self) -> DitherStatus {
        let mut status = self.dither.status(&self.dither_config);
        if self.dither.enabled() {
            status.state = firmware::dither::DitherState::Locked;
        }
        status
    }

    fn dither_setpoints(&mut self) -> DitherSetpoints {
        self.dither.setpoints()
    }

    fn apply_dither(&mut self, setpoints: DitherSetpoints) -> Result<(), CommandError> {
        self.dither.apply_setpoints(&self.dither_config, setpoints)
    }
    fn strip_coefficients(&mut self) -> Option<StripCoefficients> {
        self.strip
    }
    fn apply_strip(&mut self, strip: StripCoefficients) {
        self.strip = Some(strip);
    }

    /// The OTP model: written once; a failing write (`FAIL_STORE`) leaves it blank.
    fn program_key(&mut self, key: &Key) -> Result<(), KeyWriteError> {
        if self.otp_key.is_some() {
            return Err(KeyWriteError::NotBlank);
        }
        if core::mem::take(&mut self.fail_next_store) {
            return Err(KeyWriteError::Failed);
        }
        self.otp_key = Some(*key);
        Ok(())
    }

    fn thermal(&mut self) -> ThermalState {
        self.thermal
    }

    fn set_thermal_model(&mut self, model: Option<ThermalModel>, enabled: bool) {
        self.thermal
            .set_model(model, enabled, IDENTITY.scale_factor_arcsec);
    }
}

fn report(outcome: LoadOutcome) -> LoadReport {
    LoadReport {
        outcome,
        newer_format: None,
        rejected_records: 0,
        damaged_bytes: 0,
    }
}

/// What a host can observe of the device's state (at the same instant).
#[derive(Clone, Debug, PartialEq)]
struct Observation {
    /// `status` (the lock state included), `cal status`, `get coeffs`, `thermal model`.
    answers: [String; 4],
    settings: CompensationSettings,
    stored: Vec<CalibrationRecord>,
    otp_key: Option<Key>,
    streaming: bool,
    dither: DitherSetpoints,
    /// The command echoed for confirmation, waiting for `yes`.
    pending: Option<Command>,
}

fn observe(executor: &Executor, device: &MemDevice, id: &Identity) -> Observation {
    let (mut e, mut d) = (executor.clone(), device.clone());
    let answers = ["status", "cal status", "get coeffs", "thermal model"].map(|q| {
        let command = parse(q).expect("query parses");
        e.execute(id, &mut d, command)
            .finish(false)
            .as_str()
            .to_owned()
    });
    Observation {
        answers,
        settings: d.active_settings(),
        stored: device.stored.clone(),
        otp_key: device.otp_key,
        streaming: executor.streaming(),
        dither: device.dither.setpoints(),
        pending: executor.pending(),
    }
}

/// The protocol run over one byte string.
struct Harness {
    executor: Executor,
    device: MemDevice,
    identity: Identity,
    line: LineAssembler,
    cycle: u32,
}

impl Harness {
    fn new(identity: Identity) -> Self {
        let report = report(LoadOutcome::Defaults {
            reason: DefaultsReason::Erased,
        });
        Self {
            executor: Executor::new(&report, None, 0, AcceptanceLimits::DEFAULT),
            device: MemDevice {
                now_ms: 0,
                active: CalibrationRecord::DEFAULTS.settings,
                staged: None,
                stored: Vec::new(),
                fail_next_store: false,
                dither_config: DitherConfig::for_profile(&BoardProfile::F405),
                dither: {
                    let mut c =
                        DitherController::new(&DitherConfig::for_profile(&BoardProfile::F405));
                    c.enable();
                    c
                },
                strip: None,
                otp_key: None,
                thermal: ThermalState::new(),
            },
            identity,
            line: LineAssembler::new(),
            cycle: 0,
        }
    }

    /// Dither cycles with varied lock-in terms (so that fits pass or are refused); the staged
    /// settings take effect at the first cycle boundary.
    fn run_cycles(&mut self, n: u32) {
        if let Some(s) = self.device.staged.take() {
            self.device.active = s;
        }
        for _ in 0..n {
            self.cycle = self.cycle.wrapping_add(1);
            let k = self.cycle as f32;
            let terms = LockinTerms {
                p1_s: 2.0e-5 * (k * 0.37).sin(),
                p2_s: 1.5e-5 * (k * 0.11 + 1.0).sin(),
            };
            let increment_q32 = 0x3_0000_0000i64 + (self.cycle as i64 % 97) * 0x100_0000;
            let increment = PhaseDelta::from_q32(increment_q32);
            let record = CycleRecord {
                output: CycleOutput {
                    increment,
                    correction: PhaseDelta::ZERO,
                    duration_ticks: 215_938,
                    flags: if self.cycle.is_multiple_of(211) {
                        CycleFlags::COUNTER_GLITCH
                    } else {
                        CycleFlags::empty()
                    },
                },
                raw_increment: increment,
                terms,
                end_phase: TotalPhase::from_q32(increment_q32.wrapping_mul(self.cycle as i64)),
                dither_amplitude_rad: 9.5,
                dither_hz: 389.0,
            };
            let actions = self.executor.on_cycle(&record, 1.0 / 389.0);
            if let Some(settings) = actions.stage {
                self.device.stage_settings(settings);
            }
            if let Some(frame) = actions.frame {
                let mut buf = [0u8; MAX_FRAME];
                let len = encode_frame(&frame, &mut buf);
                assert_eq!(buf[len - 1], 0, "frame delimiter");
                assert!(buf[..len - 1].iter().all(|&b| b != 0), "no 0x00 inside");
                assert_eq!(decode_frame(&buf[..len - 1]), Ok(frame), "round trip");
            }
        }
    }

    fn on_event(&mut self, event: Event) {
        // The state as the rules predict it after any line: a pending confirmation dropped.
        let mut expected = self.executor.clone();
        expected.drop_pending();
        let before = observe(&expected, &self.device, &self.identity);
        // The firmware's own line-answering path (the one the command service runs).
        let line_event = match &event {
            Event::TooLong => LineEvent::TooLong,
            Event::Garbage => LineEvent::Garbage,
            Event::Line(text) => LineEvent::Line(text),
        };
        let answer = endpoint::answer(
            line_event,
            &mut self.executor,
            &self.identity,
            &mut self.device,
        );
        let answer = answer.as_str();
        let with_crc = matches!(&event, Event::Line(text) if has_valid_crc(text));
        let code = check_answer(answer, Some(with_crc));
        match (&event, code) {
            (Event::TooLong, c) => assert_eq!(c, Some(7), "{answer:?}"),
            (Event::Garbage, c) => assert_eq!(c, Some(8), "{answer:?}"),
            (Event::Line(_), _) => {}
        }
        let after = || observe(&self.executor, &self.device, &self.identity);
        match code {
            None | Some(12) => {}
            Some(15) => {
                let after = after();
                assert!(after.answers[0].contains("locked=yes"), "{after:?}");
                assert_eq!(after.pending, None, "{event:?}");
            }
            Some(18) => {
                // The echo: nothing executed, exactly the line's command pending.
                let after = after();
                let Event::Line(text) = &event else {
                    panic!("an echo of no line: {event:?}");
                };
                let body = strip_checksum(text).expect("the line was a command").0;
                assert_eq!(after.pending, parse(body).ok(), "{event:?} -> {answer}");
                let unchanged = Observation {
                    pending: None,
                    ..after
                };
                assert_eq!(before, unchanged, "the echo changed the state: {event:?}");
            }
            Some(_) => {
                assert_eq!(
                    before,
                    after(),
                    "an ERR changed the state: {event:?} -> {answer}"
                );
            }
        }
    }
}

/// A completed line, owned (the assembler's borrow ends before the executor runs).
#[derive(Debug)]
enum Event {
    Line(String),
    TooLong,
    Garbage,
}

/// Runs the protocol over `data` and checks every answer (panics on a broken promise).
pub fn check(data: &[u8]) {
    let (identity, data) = match data.split_first() {
        Some((&BLANK_OTP, rest)) => (
            Identity {
                key: None,
                ..IDENTITY
            },
            rest,
        ),
        _ => (IDENTITY, data),
    };
    let mut h = Harness::new(identity);
    let mut lines = LineCounter::default();
    let mut events = 0usize;
    for &byte in data {
        match byte {
            TICK => h.device.now_ms = h.device.now_ms.wrapping_add(60_000),
            TICK_SHORT => h.device.now_ms = h.device.now_ms.wrapping_add(3_000),
            CYCLES => h.run_cycles(400),
            FAIL_STORE => h.device.fail_next_store = true,
            NEW_SESSION => {
                h.executor.new_session();
                h.line = LineAssembler::new();
                lines.restart();
                let now = observe(&h.executor, &h.device, &h.identity);
                assert!(now.answers[0].contains(" locked=yes "), "{now:?}");
                assert!(!now.streaming, "a new session streams nothing");
                assert_eq!(now.pending, None, "nothing pending");
            }
            _ => {
                h.device.now_ms = h.device.now_ms.wrapping_add(7);
                lines.push(byte);
                let event = match h.line.push(byte) {
                    None => continue,
                    Some(LineEvent::Line(text)) => Event::Line(text.to_owned()),
                    Some(LineEvent::TooLong) => Event::TooLong,
                    Some(LineEvent::Garbage) => Event::Garbage,
                };
                events += 1;
                h.on_event(event);
            }
        }
    }
    assert_eq!(events, lines.lines, "one answer per non-empty line");
}
