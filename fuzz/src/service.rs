//! The `service` target: arbitrary serial bytes through the firmware's command service
//! (`Service::pass`, the board's main loop, and so `on_byte`, `on_cycle`, `on_output`), with
//! the board's record queue (`service::record_queue`, overfilled: lost cycles), new sessions,
//! resets through `service::power_up` with the wrong-key count kept in the ports' backup RAM,
//! a RAM flash whose writes can fail, and a board with or without a key in its OTP.
//!
//! Checked, besides no panic:
//! - exactly one answer per non-empty line (counted independently), each well formed;
//! - every frame decodes (cycle or output frame); the cycle stream's sequence never steps
//!   back or repeats between resets (a lost cycle is a gap forward, in its place);
//! - the wrong-key count the service saves for the backup domain is the number of `ERR 15`
//!   since the last `OK unlocked`, across resets;
//! - after a new session the board is locked and not streaming (a `status` the harness sends
//!   is answered in plain text with `locked=yes`).
//!
//! Event bytes: [`super::events`].

use std::collections::VecDeque;

use embedded_storage::nor_flash::{ErrorType, NorFlash, ReadNorFlash};
use firmware::dither::{DitherConfig, DitherController};
use firmware::profile::BoardProfile;
use firmware::protocol::execute::Identity;
use firmware::protocol::key::Key;
use firmware::protocol::link::KeyWriteError;
use firmware::protocol::output_frame::decode_output_frame;
use firmware::protocol::stream::{decode_frame, sequence_step};
use firmware::protocol::thermal_frame::decode_thermal_frame;
use firmware::readout::Readout;
use firmware::service::ports::{Clock, DitherAccess, ReadoutAccess, Secrets, SerialTx};
use firmware::service::power_up::power_up;
use firmware::service::record_queue::{LossyProducer, Tagged};
use firmware::service::{Service, ServiceConfig};
use firmware::signal::lockin::{CycleFlags, CycleOutput, CycleRecord, LockinTerms};
use firmware::signal::output::record::{OutputRecord, OutputStatus};
use firmware::storage::ram_flash::{RamFlash, RamFlashError};
use firmware::storage::Geometry;
use firmware::units::{PhaseDelta, TotalPhase};

use super::answers::{check_answer, split_output, LineCounter};
use super::events::{BLANK_OTP, CYCLES, FAIL_STORE, NEW_SESSION, OUTPUTS, RESET, TICK, TICK_SHORT};
use super::protocol::IDENTITY;

/// Two sectors of 512 bytes: room for three records each, so stores soon erase.
type Ram = RamFlash<2, 512>;

/// The RAM flash with a failure to inject: the next write fails.
pub struct FailingFlash {
    flash: Ram,
    fail_next_write: bool,
}

impl ErrorType for FailingFlash {
    type Error = RamFlashError;
}

impl ReadNorFlash for FailingFlash {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), RamFlashError> {
        self.flash.read(offset, bytes)
    }
    fn capacity(&self) -> usize {
        self.flash.capacity()
    }
}

impl NorFlash for FailingFlash {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = 512;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), RamFlashError> {
        self.flash.erase(from, to)
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), RamFlashError> {
        if std::mem::take(&mut self.fail_next_write) {
            return Err(RamFlashError::OutOfBounds);
        }
        self.flash.write(offset, bytes)
    }
}

/// The board's ports in plain memory: a clock, the transmitter, the readout, the drive, the
/// OTP and the backup RAM.
struct Ports {
    readout: Readout,
    drive_config: DitherConfig,
    drive: DitherController,
    now_ms: u64,
    out: Vec<u8>,
    otp_key: Option<Key>,
    backup_wrong_keys: u32,
}

impl Clock for Ports {
    fn now_ms(&self) -> u64 {
        self.now_ms
    }
}

impl SerialTx for Ports {
    fn send(&mut self, bytes: &[u8]) {
        self.out.extend_from_slice(bytes);
    }
    fn try_send_frame(&mut self, frame: &[u8]) -> bool {
        self.out.extend_from_slice(frame);
        true
    }
}

impl ReadoutAccess for Ports {
    fn with_readout<R>(&mut self, f: impl FnOnce(&mut Readout) -> R) -> R {
        f(&mut self.readout)
    }
    fn stop_readout(&mut self) {}
    fn restart_readout(&mut self) {
        self.readout.resynchronise();
    }
}

impl DitherAccess for Ports {
    fn with_dither<R>(&mut self, f: impl FnOnce(&mut DitherController, &DitherConfig) -> R) -> R {
        f(&mut self.drive, &self.drive_config)
    }
}

impl Secrets for Ports {
    fn program_key(&mut self, key: &Key) -> Result<(), KeyWriteError> {
        if self.otp_key.is_some() {
            return Err(KeyWriteError::NotBlank);
        }
        self.otp_key = Some(*key);
        Ok(())
    }
    fn save_wrong_keys(&mut self, count: u32) {
        self.backup_wrong_keys = count;
    }
}

fn config(key: Option<Key>) -> ServiceConfig {
    let identity = Identity { key, ..IDENTITY };
    let geometry = Geometry {
        base_offset: 0,
        sector_bytes: 512,
    };
    ServiceConfig::for_profile(&BoardProfile::F405, 389.0, identity, geometry)
}

/// The service and what the harness knows.
struct Harness {
    service: Service<FailingFlash>,
    ports: Ports,
    input: VecDeque<u8>,
    lines: LineCounter,
    answers: usize,
    /// `ERR 15` since the last `OK unlocked`: what the backup RAM must hold.
    wrong_keys: u32,
    cycle: u32,
    output_sequence: u64,
    last_cycle_frame: Option<u32>,
}

impl Harness {
    fn boot(flash: FailingFlash, otp_key: Option<Key>, backup: u32, now_ms: u64) -> Self {
        let up = power_up(config(otp_key), flash, backup, now_ms).expect("the geometry fits");
        let drive_config = DitherConfig::for_profile(&BoardProfile::F405);
        let mut drive = DitherController::new(&drive_config);
        drive.enable();
        Self {
            service: up.service,
            ports: Ports {
                readout: up.readout,
                drive_config,
                drive,
                now_ms,
                out: Vec::new(),
                otp_key,
                backup_wrong_keys: backup,
            },
            input: VecDeque::new(),
            lines: LineCounter::default(),
            answers: 0,
            wrong_keys: backup,
            cycle: 0,
            output_sequence: 0,
            last_cycle_frame: None,
        }
    }

    fn cycle_record(&mut self) -> CycleRecord {
        self.cycle = self.cycle.wrapping_add(1);
        let k = self.cycle as f32;
        let increment_q32 = 0x3_0000_0000i64 + (self.cycle as i64 % 97) * 0x100_0000;
        let increment = PhaseDelta::from_q32(increment_q32);
        CycleRecord {
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
            terms: LockinTerms {
                p1_s: 2.0e-5 * (k * 0.37).sin(),
                p2_s: 1.5e-5 * (k * 0.11 + 1.0).sin(),
            },
            end_phase: TotalPhase::from_q32(increment_q32.wrapping_mul(self.cycle as i64)),
            dither_amplitude_rad: 9.5,
            dither_hz: 389.0,
        }
    }

    /// Main-loop passes until idle: the waiting bytes, then `cycles` (through the board's
    /// 32-record queue: 40 closed at once, 8 dropped and counted on the next) and `outputs`.
    fn run(&mut self, cycles: usize, outputs: usize) {
        let mut queue: heapless::spsc::Queue<Tagged<CycleRecord>, 33> =
            heapless::spsc::Queue::new();
        let (producer, mut consumer) = queue.split();
        let mut producer = LossyProducer::new(producer);
        let mut records = VecDeque::new();
        for _ in 0..outputs {
            self.output_sequence += 1;
            records.push_back(OutputRecord {
                sequence: self.output_sequence,
                time_ticks: self.output_sequence * 84_000,
                period_ticks: 84_000,
                delta_angle_q16: 3,
                angle_q16: self.output_sequence as i64 * 3,
                rate_deg_per_h: 13.9,
                status: OutputStatus::VALID,
                temperature_q7: firmware::thermal::state::NO_VALUE,
                temperature_rate_centi_c_per_min: firmware::thermal::state::NO_VALUE,
            });
        }
        let mut remaining = cycles;
        loop {
            // The readout task closes 40 cycles while the main loop is away: 8 do not fit.
            let burst = remaining.min(40);
            for _ in 0..burst {
                let record = self.cycle_record();
                let _ = producer.push(record);
            }
            remaining -= burst;
            let (service, ports, input) = (&mut self.service, &mut self.ports, &mut self.input);
            let busy = service.pass(
                ports,
                |_| input.pop_front(),
                || consumer.dequeue(),
                || records.pop_front(),
            );
            self.ports.now_ms += 1;
            if !busy && remaining == 0 {
                break;
            }
        }
        self.take_output();
    }

    /// Checks and counts what the board sent.
    fn take_output(&mut self) {
        let out = split_output(&std::mem::take(&mut self.ports.out));
        for answer in &out.answers {
            let code = check_answer(answer, None);
            self.answers += 1;
            if code == Some(15) {
                self.wrong_keys = self.wrong_keys.saturating_add(1);
            } else if code.is_none() && answer.starts_with("OK unlocked") {
                self.wrong_keys = 0;
            }
        }
        for frame in &out.frames {
            if let Ok(record) = decode_frame(frame) {
                if let Some(last) = self.last_cycle_frame {
                    assert!(
                        sequence_step(last, record.sequence).is_some(),
                        "cycle frames went from {last} to {}",
                        record.sequence
                    );
                }
                self.last_cycle_frame = Some(record.sequence);
            } else {
                assert!(
                    decode_output_frame(frame).is_ok() || decode_thermal_frame(frame).is_ok(),
                    "a bad frame: {frame:?}"
                );
            }
        }
        assert_eq!(
            self.ports.backup_wrong_keys, self.wrong_keys,
            "the wrong-key count kept for a reset"
        );
    }

    fn check_answered(&self) {
        assert_eq!(
            self.answers, self.lines.lines,
            "one answer per non-empty line"
        );
    }
}

/// Runs the service over `data` (panics on a broken promise).
pub fn check(data: &[u8]) {
    let (otp_key, data) = match data.split_first() {
        Some((&BLANK_OTP, rest)) => (None, rest),
        _ => (IDENTITY.key, data),
    };
    let flash = FailingFlash {
        flash: Ram::new(),
        fail_next_write: false,
    };
    let mut h = Harness::boot(flash, otp_key, 0, 0);
    for &byte in data {
        let (cycles, outputs) = match byte {
            TICK => {
                h.ports.now_ms += 60_000;
                (0, 0)
            }
            TICK_SHORT => {
                h.ports.now_ms += 3_000;
                (0, 0)
            }
            CYCLES => (100, 0),
            OUTPUTS => (0, 20),
            FAIL_STORE => {
                h.run(0, 0);
                h.service.flash_mut().fail_next_write = true;
                continue;
            }
            NEW_SESSION => {
                h.run(0, 0);
                h.service.new_session();
                h.lines.restart();
                h.check_answered();
                for &b in b"status\n" {
                    h.input.push_back(b);
                    h.lines.push(b);
                }
                let (service, ports, input) = (&mut h.service, &mut h.ports, &mut h.input);
                while service.pass(ports, |_| input.pop_front(), || None, || None) {}
                // Answered in plain text (no stream), locked.
                let raw = String::from_utf8_lossy(&h.ports.out).into_owned();
                assert!(raw.starts_with("OK "), "{raw:?}");
                assert!(raw.contains(" locked=yes "), "{raw:?}");
                h.take_output();
                continue;
            }
            RESET => {
                h.run(0, 0);
                h.check_answered();
                let now_ms = h.ports.now_ms;
                let (backup, otp, counted) =
                    (h.ports.backup_wrong_keys, h.ports.otp_key, h.answers);
                let lines = h.lines.clone();
                let flash = h.service.into_flash();
                h = Harness::boot(flash, otp, backup, now_ms);
                (h.answers, h.lines) = (counted, lines);
                h.lines.restart();
                continue;
            }
            _ => {
                h.ports.now_ms += 7;
                h.input.push_back(byte);
                h.lines.push(byte);
                continue;
            }
        };
        h.run(cycles, outputs);
        h.check_answered();
    }
    h.run(0, 0);
    h.check_answered();
}
