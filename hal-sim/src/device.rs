//! The simulated board running the firmware: gyro, peripherals, the firmware's readout, its
//! calibration store on the simulated flash, and its serial protocol, behind one serial link.
//!
//! [`SimDevice`] is what a host tool or a person at a terminal talks to in place of a board:
//! bytes in ([`SimDevice::receive`]), bytes out ([`SimDevice::take_output`]), simulated time
//! advanced explicitly ([`SimDevice::run_for`]). Every line is executed by the firmware's own
//! `protocol` code against the firmware's own `Readout`, `CalibrationSession` and
//! `CalibrationStore`; only the peripherals are simulated.
//!
//! Like the board, a `store` stalls: the flash model books the erase and programming time, the
//! simulated gyro runs on meanwhile without the readout seeing it, and the readout is
//! re-synchronised afterwards. Power can be cut ([`SimDevice::power_off`] returns the flash,
//! whose contents survive; [`SimDevice::boot`] starts again from it).
//!
//! While streaming, cycle frames (COBS, ending in 0x00) and text answers share the line: a text
//! answer to a line sent while streaming (`stream off` included) is wrapped in 0x00 delimiters,
//! so a host splitting at 0x00 sees either a frame or a line starting with `OK`/`ERR` (text
//! never contains 0x00); the answer to `stream on` is still plain text.

use crate::board::{BoardConfig, BoardError, SimBoard};
use crate::flash::{CalibrationFlash, FlashError};
use crate::gyro::Gyro;
use crate::input::InputProfile;
use crate::params::GyroParams;
use firmware::calibration::validation::AcceptanceLimits;
use firmware::protocol::endpoint;
use firmware::protocol::execute::{DeviceLink, DeviceStatus, Executor, Identity};
use firmware::protocol::line::{LineAssembler, LineEvent};
use firmware::protocol::stream::{encode_frame, MAX_FRAME};
use firmware::readout::{Readout, ReadoutConfig};
use firmware::signal::compensation::CompensationSettings;
use firmware::signal::output::{AveragerConfig, AveragingMode, RateAverager};
use firmware::storage::ReadoutPaused;
use firmware::storage::{CalibrationRecord, CalibrationStore, Geometry, LoadReport, StoreError};

/// The simulated board with its firmware.
pub struct SimDevice {
    board: SimBoard,
    config: ReadoutConfig,
    readout: Readout,
    flash: CalibrationFlash,
    store: CalibrationStore,
    executor: Executor,
    identity: Identity,
    line: LineAssembler,
    averager: RateAverager,
    averager_config: AveragerConfig,
    status: DeviceStatus,
    output: Vec<u8>,
    lissajous: Vec<(u16, u16)>,
    /// Simulated seconds the CPU is still stalled by a flash operation.
    stall_s: f64,
}

/// An identity for simulated boards.
pub const SIM_IDENTITY: Identity = Identity {
    firmware_version: env!("CARGO_PKG_VERSION"),
    build: "hal-sim",
    board: "rlg-readout-sim",
    serial_number: 4242,
    key: 0xC0FF_EE42,
    scale_factor_arcsec: 1.8655,
    capture_timer_hz: 84_000_000,
};

impl SimDevice {
    /// Powers up a board on `flash`: loads the newest valid calibration (or the defaults) and
    /// starts the readout with it, locked, as the firmware does at reset.
    pub fn boot(
        params: GyroParams,
        input: InputProfile,
        identity: Identity,
        mut flash: CalibrationFlash,
        boot_count: u32,
    ) -> Result<Self, BoardError> {
        let gyro =
            Gyro::new(params, input).map_err(|_| BoardError::Config("invalid gyro parameters"))?;
        let board_config = BoardConfig::for_gyro(&params);
        let board = SimBoard::new(gyro, board_config.clone())?;
        let config = ReadoutConfig::for_board(
            board_config.timer_hz,
            params.dither_hz,
            firmware::profile::BoardProfile::F405.counter_width,
        );
        let store = CalibrationStore::new(&flash, Geometry::F405_CALIBRATION_AREA)
            .map_err(|_| BoardError::Config("flash geometry"))?;
        flash.power_on();
        let (record, report) = store.load(&mut flash);
        Ok(Self {
            readout: Readout::new(&config, record.settings),
            executor: Executor::new(&report, record.fit, boot_count, AcceptanceLimits::DEFAULT),
            averager_config: AveragerConfig {
                window_cycles: params.dither_hz.round().max(1.0) as u32,
                mode: AveragingMode::WholePeriods,
                timer_hz: board_config.timer_hz,
                scale_factor_arcsec: params.scale_factor_arcsec,
            },
            averager: RateAverager::new(),
            status: DeviceStatus::default(),
            line: LineAssembler::new(),
            output: Vec::new(),
            lissajous: Vec::new(),
            stall_s: 0.0,
            identity,
            board,
            config,
            flash,
            store,
        })
    }

    /// Cuts the power: returns the flash, whose contents survive.
    pub fn power_off(mut self) -> CalibrationFlash {
        self.flash.power_off();
        self.flash
    }

    /// The simulated flash (e.g. to arm a power cut).
    pub fn flash_mut(&mut self) -> &mut CalibrationFlash {
        &mut self.flash
    }

    /// The firmware's readout state.
    pub fn readout(&self) -> &Readout {
        &self.readout
    }

    /// Simulated time, s.
    pub fn time_s(&self) -> f64 {
        self.board.time_s()
    }

    /// Runs the gyro and the firmware for `seconds` of simulated time.
    pub fn run_for(&mut self, seconds: f64) {
        let end = self.board.time_s() + seconds;
        while self.board.time_s() < end {
            self.half_cycle();
        }
    }

    /// One half dither cycle: the ADC stream and the turnaround interrupt, then the cycle task.
    fn half_cycle(&mut self) {
        let sample = self.board.next_half_cycle(&mut self.lissajous);
        if self.stall_s > 0.0 {
            // The CPU is stalled by the flash: the peripherals run on, the firmware sees nothing.
            self.stall_s -= 0.5 / self.board.gyro().params().dither_hz;
            if self.stall_s <= 0.0 {
                self.readout.resynchronise();
            }
            return;
        }
        for &(a, b) in &self.lissajous {
            self.readout.on_lissajous_sample(&self.config, a, b);
        }
        let Some(record) = self.readout.on_turnaround(&self.config, sample) else {
            return;
        };
        self.board.on_cycle(&record);
        let reading = self.averager.push(&self.averager_config, record.output);
        self.status.on_cycle(record.output.flags, reading);
        let cycle_s = record.duration_s(&self.config.cycle);
        let actions = self.executor.on_cycle(&record, cycle_s);
        if let Some(settings) = actions.stage {
            self.readout.stage_compensation(settings);
        }
        if let Some(frame) = actions.frame {
            let mut buf = [0u8; MAX_FRAME];
            let n = encode_frame(&frame, &mut buf);
            self.output.extend_from_slice(&buf[..n]);
        }
    }

    /// Serial bytes from the host: every completed line is executed and answered at once, by
    /// the same `protocol::endpoint` functions the board runs.
    pub fn receive(&mut self, bytes: &[u8]) {
        for &byte in bytes {
            // Framing follows the mode the host was in when it sent the line.
            let streaming = self.executor.streaming();
            let Some(event) = self.line.push(byte) else {
                continue;
            };
            let event = match event {
                LineEvent::Line(text) => OwnedEvent::Line(text.to_owned()),
                LineEvent::TooLong => OwnedEvent::TooLong,
                LineEvent::Garbage => OwnedEvent::Garbage,
            };
            self.refresh_status();
            let mut link = Link {
                readout: &mut self.readout,
                flash: &mut self.flash,
                store: &self.store,
                status: self.status,
                now_ms: (self.board.time_s() * 1000.0) as u32,
                stall_s: &mut self.stall_s,
            };
            let answer = endpoint::answer(
                event.as_event(),
                &mut self.executor,
                &self.identity,
                &mut link,
            );
            let output = &mut self.output;
            endpoint::send_answer(streaming, &answer, |b| output.extend_from_slice(b));
        }
    }

    fn refresh_status(&mut self) {
        self.status
            .update_from(&self.readout.counters(), self.readout.dither());
    }

    /// Everything sent to the host since the last call.
    pub fn take_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.output)
    }
}

/// A line event that outlives the assembler's buffer (the device is borrowed while answering).
enum OwnedEvent {
    Line(String),
    TooLong,
    Garbage,
}

impl OwnedEvent {
    fn as_event(&self) -> LineEvent<'_> {
        match self {
            Self::Line(text) => LineEvent::Line(text),
            Self::TooLong => LineEvent::TooLong,
            Self::Garbage => LineEvent::Garbage,
        }
    }
}

/// The firmware's view of the device during one command.
struct Link<'a> {
    readout: &'a mut Readout,
    flash: &'a mut CalibrationFlash,
    store: &'a CalibrationStore,
    status: DeviceStatus,
    now_ms: u32,
    stall_s: &'a mut f64,
}

impl DeviceLink for Link<'_> {
    type FlashError = FlashError;

    fn now_ms(&self) -> u32 {
        self.now_ms
    }

    fn status(&self) -> DeviceStatus {
        self.status
    }

    fn active_settings(&self) -> CompensationSettings {
        self.readout.staged_or_active_compensation()
    }

    fn stage_settings(&mut self, settings: CompensationSettings) {
        self.readout.stage_compensation(settings);
    }

    fn store(&mut self, record: &CalibrationRecord) -> Result<u32, StoreError<FlashError>> {
        let before = self.flash.stats().busy_s;
        let result =
            self.store
                .store_while_paused(self.flash, &ReadoutPaused::assume_paused(), record);
        // The stall: the readout misses what happens meanwhile and re-synchronises after it.
        *self.stall_s += (self.flash.stats().busy_s - before).max(1e-3);
        result
    }

    fn load(&mut self) -> (CalibrationRecord, LoadReport) {
        self.store.load(self.flash)
    }
}
