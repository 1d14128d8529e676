//! The simulated board running the firmware: gyro, peripherals, the firmware's readout, its
//! calibration store on the simulated flash, and its serial protocol, behind one serial link.
//!
//! [`SimDevice`] is what a host tool or a person at a terminal talks to in place of a board:
//! bytes in ([`SimDevice::receive`]), bytes out ([`SimDevice::take_output`]), simulated time
//! advanced explicitly ([`SimDevice::run_for`]). It runs the firmware's own command service
//! (`firmware::service::Service`, the very one the board's main loop runs) against the
//! firmware's own `Readout`; only the peripherals are simulated, behind the service's ports
//! (simulated time, an output buffer, the readout in plain memory) and the NOR flash model.
//!
//! Like the board, a `store` stalls its fetches from flash for as long as the flash model books
//! the programming and, when a sector is full, the erase (typical datasheet times: 16 us per
//! word, 1 s per sector). The stall model follows the silicon (`firmware::board::ram`):
//! - what runs from RAM goes on: the dither drive's tick coasts on the drive in force
//!   ([`crate::drive_loop::FirmwareDrive::coast_until`]) and the controller takes over again
//!   after; the serial link queues what arrives (on the board 511 bytes, here without a
//!   limit); the millisecond clock keeps time;
//! - the peripherals go on (the gyro, the counter, the latches' hardware, the pick-off stream);
//! - the main loop is stalled: the answer to `store` comes when the store is over, then the
//!   bytes received meanwhile are taken, then the records the readout made meanwhile;
//! - the readout's handlers (in flash) are only delayed by a word's programming: a store
//!   without an erase leaves the readout running (what a handler delayed by at most one word,
//!   16 us, changes is not modelled: an output latch armed that much later); a store that
//!   erases pauses the readout from the command to the end of the store, and re-synchronises
//!   it after (`store` answers `readout=resynchronised`).
//!
//! Power can be cut ([`SimDevice::power_off`] returns the flash,
//! whose contents survive; [`SimDevice::boot`] starts again from it).
//!
//! While streaming, cycle frames (COBS, ending in 0x00) and text answers share the line: a text
//! answer is wrapped in 0x00 delimiters when a stream is on before or after its line (`stream
//! on`, `stream output` and `stream off` included), so a host splitting at 0x00 sees either a
//! frame or a line starting with `OK`/`ERR` (text never contains 0x00).
//!
//! The board watches itself as the real one does (`firmware::board_timing`): at power-up the
//! self-test's clock, timer and trigger checks (measured on the simulated board,
//! [`crate::board::BoardFaults::selftest`]) and the drive's pick-off check (the half-drive
//! sweep, against the simulated resonator and pick-off); while it runs, the rate monitors on
//! the events the simulated board counts ([`Harness::event_counts`]), once per half cycle as
//! the board's main loop does once per pass, with the same reactions (output records marked
//! `TIMING_FAULT`, the drive taken off for a stopped drive tick or a lost clock). Faults are
//! injected at power-up ([`SimDevice::boot_with_faults`]) or while running
//! ([`SimDevice::inject`]).

use crate::board::{BoardConfig, BoardError, BoardFault, LatchTiming};
use crate::dither::resonator::ResonatorParams;
use crate::drive_loop::FirmwareDrive;
use crate::flash::CalibrationFlash;
use crate::harness::{DriveSource, Feed, Harness, HarnessError, HarnessOptions};
use firmware::board_timing::health::BoardHealth;
use firmware::board_timing::monitor::{Event, TimingFaults, TimingWatch};
use firmware::board_timing::selftest::SelfTestReport;
use firmware::dither::DitherState;
use firmware::signal::output::record::OutputRecord;
use firmware::signal::output::record::OutputStatus;

/// The simulated board's output rate without an external sync: the board's internal output
/// timer, Hz.
pub const OUTPUT_RATE_HZ: f64 = 1000.0;
use crate::input::InputProfile;
use crate::params::GyroParams;
use firmware::dither::{DitherConfig, DitherController};
use firmware::profile::BoardProfile;
use firmware::protocol::execute::Identity;
use firmware::protocol::key::Key;
use firmware::protocol::link::KeyWriteError;
use firmware::readout::Readout;
use firmware::service::ports::{Clock, DitherAccess, ReadoutAccess, Secrets, SerialTx};
use firmware::service::{Service, ServiceConfig};
use firmware::storage::Geometry;

/// The simulated board with its firmware.
pub struct SimDevice {
    /// The gyro, the peripherals and the firmware's readout (firmware in the loop).
    harness: Harness,
    /// The firmware's command service, the board's main loop.
    service: Service<CalibrationFlash>,
    /// Bytes sent to the host, not yet taken.
    output: Vec<u8>,
    /// The flash stall in progress, if any.
    stall: Option<Stall>,
    /// The simulated OTP key words: the identity's key at boot, or what `key provision` wrote.
    otp_key: Option<Key>,
    /// The power-up self-test's clock, timer and trigger checks.
    selftest: SelfTestReport,
    /// The rate monitors.
    watch: TimingWatch,
    /// The drive was taken off for a stopped drive tick or a lost clock.
    drive_taken_off: bool,
}

/// A flash stall: the main loop is stalled until `until_s` (simulated time), and what waits for
/// it. An absolute deadline, so the time a step overshoots it is never carried into the next
/// stall.
struct Stall {
    until_s: f64,
    /// The store erased a sector: the readout is paused until `until_s` and re-synchronised
    /// then. Without an erase it runs on, and its records wait in `held_records`.
    readout_paused: bool,
    /// Output records and closed cycles the readout made during the stall, for the main loop.
    held_records: Vec<Held>,
    /// The answer of the command that stalled, sent when the stall is over (as on the board,
    /// whose main loop sends it after the store returns).
    held_output: Vec<u8>,
    /// Bytes that arrived during the stall, taken when it is over.
    held_input: Vec<u8>,
}

/// A record the readout made while the main loop was stalled.
enum Held {
    Output(OutputRecord),
    Cycle(firmware::signal::lockin::CycleRecord),
}

/// An identity for simulated boards: unprovisioned. A simulated board with a key is
/// `Identity { key: Some(key), ..SIM_IDENTITY }`, the key given on its command line (rlg-cal's
/// `--board-key` / `RLG_SIM_BOARD_KEY`); there is no fixed simulator key.
pub const SIM_IDENTITY: Identity = Identity {
    firmware_version: env!("CARGO_PKG_VERSION"),
    build: "hal-sim",
    board: "rlg-readout-sim",
    serial_number: 4242,
    key: None,
    scale_factor_arcsec: BoardProfile::F405.scale_factor_arcsec as f32,
    capture_timer_hz: BoardProfile::F405.timer_hz,
};

impl SimDevice {
    /// Powers up a board on `flash`: loads the newest valid calibration (or the defaults) and
    /// starts the readout with it, locked, as the firmware does at reset. The board's profile is
    /// the simulated board's ([`BoardConfig::profile`]), built for this gyro (its nominal dither
    /// and scale factor).
    pub fn boot(
        params: GyroParams,
        input: InputProfile,
        identity: Identity,
        flash: CalibrationFlash,
        boot_count: u32,
    ) -> Result<Self, BoardError> {
        Self::boot_with_faults(params, input, identity, flash, boot_count, &[])
    }

    /// [`Self::boot`] on a board with `faults` from the start: the power-up self-test meets
    /// them.
    pub fn boot_with_faults(
        params: GyroParams,
        input: InputProfile,
        identity: Identity,
        mut flash: CalibrationFlash,
        boot_count: u32,
        faults: &[BoardFault],
    ) -> Result<Self, BoardError> {
        // A board drives its dither: a prescribed sine becomes the resonator it stands for
        // (at its frequency, in the steady state of its amplitude), and the firmware's drive
        // holds it from power-up on.
        let params = match params.resonator() {
            Some(_) => params,
            None => params.with_steady_driven_dither(ResonatorParams {
                f0_hz: params.dither_hz,
                ..ResonatorParams::default()
            }),
        };
        // As on the board: the turnarounds latched at the instants the firmware predicts from
        // the pick-off's edges, not at the simulator's true turnarounds.
        // The output latches at the board's internal output rate (no external sync connected).
        let board = BoardConfig {
            latch: LatchTiming::scheduled(0.0),
            sync_hz: Some(OUTPUT_RATE_HZ),
            ..BoardConfig::for_gyro(&params)
        };
        let profile = BoardProfile {
            nominal_dither_hz: params.dither_hz,
            ..board.profile()
        };
        let config = ServiceConfig::for_profile(
            &profile,
            params.dither_hz,
            identity,
            Geometry::F405_CALIBRATION_AREA,
        );
        flash.power_on();
        let booted = Service::boot(config, flash, Some(boot_count))
            .map_err(|_| BoardError::Config("flash geometry"))?;
        let config_error = |e| match e {
            HarnessError::Gyro(_) => BoardError::Config("invalid gyro parameters"),
            HarnessError::Board(e) => e,
            HarnessError::Drive(_) => BoardError::Config("the drive does not fit the resonator"),
        };
        let mut harness = HarnessOptions {
            board,
            drive: DriveSource::firmware(&params).map_err(config_error)?,
            ..HarnessOptions::new(params, input)
        }
        .compensation(booted.settings)
        .build()
        .map_err(config_error)?;
        if let Some(strip) = booted.strip {
            // As `board::app::boot`: the stripping starts from the stored K.
            let config = *harness.config();
            harness
                .readout_mut()
                .restart_strip_from(&config, strip.k(), strip.k_quadrature());
        }
        for &fault in faults {
            harness.board_mut().inject(fault);
        }
        // As on the board, the command service keeps the thermal state (`thermal`); the
        // harness only polls the sensor.
        harness.hand_over_thermal();
        // As `board::app::run`: the clock, timer and trigger checks, then the drive with its
        // stored setpoints, its pick-off check first (or inhibited).
        let selftest = harness.board().faults().selftest();
        if let Some(drive) = harness.firmware_drive_mut() {
            drive.power_up(booted.dither, Some(&selftest));
        }
        Ok(Self {
            harness,
            service: booted.service,
            output: Vec::new(),
            stall: None,
            otp_key: identity.key,
            selftest,
            watch: TimingWatch::new(),
            drive_taken_off: false,
        })
    }

    /// Cuts the power: returns the flash, whose contents survive.
    pub fn power_off(self) -> CalibrationFlash {
        let mut flash = self.service.into_flash();
        flash.power_off();
        flash
    }

    /// Injects a fault while the board runs ([`BoardFault`]; at power-up:
    /// [`Self::boot_with_faults`]).
    pub fn inject(&mut self, fault: BoardFault) {
        self.harness.board_mut().inject(fault);
    }

    /// The board's health as `status` and `selftest` report it.
    pub fn board_health(&self) -> BoardHealth {
        BoardHealth {
            selftest: self.selftest,
            timing: self.watch.faults(),
            emulated: false,
        }
    }

    /// The simulated flash (e.g. to arm a power cut).
    pub fn flash_mut(&mut self) -> &mut CalibrationFlash {
        self.service.flash_mut()
    }

    /// The firmware's readout state.
    pub fn readout(&self) -> &Readout {
        self.harness.readout()
    }

    /// The dither drive's state now (the firmware's controller: `status`'s `drive=`).
    pub fn dither_state(&self) -> DitherState {
        self.harness
            .firmware_drive()
            .map_or(DitherState::Off, |d| d.controller().state())
    }

    /// Simulated time, s.
    pub fn time_s(&self) -> f64 {
        self.harness.time_s()
    }

    /// Runs the gyro and the firmware for `seconds` of simulated time.
    pub fn run_for(&mut self, seconds: f64) {
        let end = self.harness.time_s() + seconds;
        while self.harness.time_s() < end {
            self.half_cycle();
        }
    }

    /// One half dither cycle: the ADC stream and the turnaround interrupt (the harness), then
    /// the main loop's cycle work (the service).
    fn half_cycle(&mut self) {
        if let Some(stall) = &self.stall {
            if stall.readout_paused {
                // An erase: the readout's handlers are masked, the peripherals run on.
                self.harness.step_with(Feed::Stalled);
            } else {
                // The readout runs; the main loop is stalled: its records wait.
                let record = self.harness.step().record;
                self.watch_pass();
                let outputs = self.harness.outputs().iter().map(|(_, r)| Held::Output(*r));
                let held: Vec<Held> = outputs.chain(record.map(Held::Cycle)).collect();
                if let Some(stall) = &mut self.stall {
                    stall.held_records.extend(held);
                }
            }
            if self
                .stall
                .as_ref()
                .is_some_and(|stall| self.harness.time_s() >= stall.until_s)
            {
                self.end_stall();
            }
            return;
        }
        let record = self.harness.step().record;
        self.watch_pass();
        // The output latches of the half cycle came first (the output latch's context), then
        // the cycle its closing turnaround made (the cycle task).
        let outputs: Vec<OutputRecord> = self.harness.outputs().iter().map(|(_, r)| *r).collect();
        let sensor_updates = self.harness.take_sensor_updates();
        let health = self.board_health();
        let mut ports = SimPorts::new(
            &mut self.harness,
            &mut self.output,
            &mut self.otp_key,
            health,
        );
        for update in sensor_updates {
            self.service.on_sensor(update, &mut ports);
        }
        for output in &outputs {
            self.service.on_output(output, &mut ports);
        }
        if let Some(record) = record {
            self.service.on_cycle(&record, &mut ports);
        }
    }

    /// The store returned: after an erase the readout re-synchronises (the rate monitors start
    /// afresh: the events stopped on purpose); its answer goes out, then the bytes that waited
    /// are taken, then the records the readout made meanwhile.
    fn end_stall(&mut self) {
        let Some(stall) = self.stall.take() else {
            return;
        };
        if stall.readout_paused {
            self.harness.readout_mut().resynchronise();
            self.watch.restart();
        }
        self.output.extend_from_slice(&stall.held_output);
        self.receive(&stall.held_input);
        let health = self.board_health();
        let mut ports = SimPorts::new(
            &mut self.harness,
            &mut self.output,
            &mut self.otp_key,
            health,
        );
        for held in &stall.held_records {
            match held {
                Held::Output(output) => self.service.on_output(output, &mut ports),
                Held::Cycle(record) => self.service.on_cycle(record, &mut ports),
            }
        }
    }

    /// The simulated temperature sensor, for fault injection.
    pub fn sensor_mut(&mut self) -> &mut crate::tmp117::SimTmp117 {
        self.harness.sensor_mut()
    }

    /// The rate monitors' pass after a half cycle (`board::watch::Watch::pass`): the events'
    /// counts and the rates expected now; a raised fault marks the output records from the
    /// next half cycle on, and a stopped drive tick or a lost clock takes the drive off.
    fn watch_pass(&mut self) {
        let now_ms = (self.harness.time_s() * 1000.0) as u64;
        let config = self.harness.board().config();
        let sync_hz = config.sync_hz.map(|hz| hz as f32);
        let lissajous_hz = (config.lissajous_rate_hz / 256.0) as f32;
        let locked_hz = self.harness.firmware_drive().and_then(|d| {
            (d.controller().state() == DitherState::Locked)
                .then(|| d.controller().estimate().frequency_hz)
        });
        let expected = [
            Some(lissajous_hz),
            Some(BoardProfile::F405.drive_tick_hz as f32),
            locked_hz.map(|hz| 2.0 * hz),
            sync_hz,
            sync_hz,
        ];
        let counts = self.harness.event_counts();
        self.watch.update(now_ms, counts, expected);
        if self.harness.board().faults().clock_lost() {
            self.watch.clock_lost();
        }
        let faults = self.watch.faults();
        let mark = if faults.is_empty() {
            OutputStatus::empty()
        } else {
            OutputStatus::TIMING_FAULT
        };
        self.harness.set_output_mark(mark);
        let drive_unsafe = faults.contains(TimingFaults::CLOCK_LOST)
            || faults.contains(TimingFaults::of(Event::DriveTick));
        if drive_unsafe && !self.drive_taken_off {
            self.drive_taken_off = true;
            self.harness.take_drive_off();
        }
    }

    /// Serial bytes from the host: every completed line is executed and answered at once, by
    /// the firmware's own command service.
    pub fn receive(&mut self, bytes: &[u8]) {
        for (i, &byte) in bytes.iter().enumerate() {
            if let Some(stall) = &mut self.stall {
                // The CPU is stalled: the rest waits (a host waits for the answer anyway).
                stall.held_input.extend_from_slice(&bytes[i..]);
                return;
            }
            let output_before = self.output.len();
            let busy_before_s = self.service.flash().stats().busy_s;
            let health = self.board_health();
            let mut ports = SimPorts::new(
                &mut self.harness,
                &mut self.output,
                &mut self.otp_key,
                health,
            );
            self.service.on_byte(byte, &mut ports);
            let readout_paused = ports.paused;
            let busy_s = self.service.flash().stats().busy_s - busy_before_s;
            if busy_s > 0.0 {
                // The flash stalled the main loop (module docs): the drive coasts, the readout
                // runs on (or, for an erase, pauses until the end of the store), and the
                // answer comes when the store is over, not before.
                let until_s = self.harness.time_s() + busy_s;
                self.stall = Some(Stall {
                    until_s,
                    readout_paused,
                    held_records: Vec::new(),
                    held_output: self.output.split_off(output_before),
                    held_input: Vec::new(),
                });
                self.harness.coast_drive(until_s);
            }
        }
    }

    /// A new client on the serial link (a served board's new connection): the firmware's
    /// session starts afresh (locked, no stream, empty line buffer), and output not yet taken,
    /// as well as the previous client's bytes and answers held by a flash stall, are dropped:
    /// they were the previous client's. The stall itself goes on (the flash is the board's).
    pub fn new_session(&mut self) {
        self.service.new_session();
        self.output.clear();
        if let Some(stall) = &mut self.stall {
            stall.held_input.clear();
            stall.held_output.clear();
        }
    }

    /// Everything sent to the host since the last call.
    pub fn take_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.output)
    }
}

/// The simulated board's ports for one service call: simulated time, the output buffer, the
/// readout and the dither controller in plain memory. A pause (an erase) only marks itself:
/// the flash model books the stall's length, which the device then lets pass with the readout
/// deaf and the drive coasting.
struct SimPorts<'a> {
    readout: &'a mut Readout,
    drive: &'a mut FirmwareDrive,
    output: &'a mut Vec<u8>,
    otp_key: &'a mut Option<Key>,
    now_ms: u64,
    paused: bool,
    health: BoardHealth,
}

impl<'a> SimPorts<'a> {
    /// The ports at the harness's present simulated time.
    fn new(
        harness: &'a mut Harness,
        output: &'a mut Vec<u8>,
        otp_key: &'a mut Option<Key>,
        health: BoardHealth,
    ) -> Self {
        // 64-bit milliseconds: no saturation at 49.7 days as a u32 would.
        let now_ms = (harness.time_s() * 1000.0) as u64;
        let (readout, drive) = harness.firmware_parts_mut();
        Self {
            now_ms,
            readout,
            drive: drive.expect("the simulated board's dither is driven by the firmware"),
            output,
            otp_key,
            paused: false,
            health,
        }
    }
}

impl DitherAccess for SimPorts<'_> {
    fn with_dither<R>(&mut self, f: impl FnOnce(&mut DitherController, &DitherConfig) -> R) -> R {
        let (controller, config) = self.drive.controller_mut();
        f(controller, config)
    }
}

impl Secrets for SimPorts<'_> {
    /// The simulated OTP: written once, refused when not blank.
    fn program_key(&mut self, key: &Key) -> Result<(), KeyWriteError> {
        if self.otp_key.is_some() {
            return Err(KeyWriteError::NotBlank);
        }
        *self.otp_key = Some(*key);
        Ok(())
    }

    /// The simulated board has no backup domain: a power cycle ([`SimDevice::power_off`],
    /// then [`SimDevice::boot`]) is a cold start, as a board without VBAT (the service's
    /// tests check that a reset keeping the count keeps the unlock windows).
    fn save_wrong_keys(&mut self, _count: u32) {}
}

impl Clock for SimPorts<'_> {
    fn now_ms(&self) -> u64 {
        self.now_ms
    }
}

impl SerialTx for SimPorts<'_> {
    fn send(&mut self, bytes: &[u8]) {
        self.output.extend_from_slice(bytes);
    }

    /// The simulated link has unbounded room: no frame is dropped here.
    fn try_send_frame(&mut self, frame: &[u8]) -> bool {
        self.output.extend_from_slice(frame);
        true
    }
}

impl ReadoutAccess for SimPorts<'_> {
    fn with_readout<R>(&mut self, f: impl FnOnce(&mut Readout) -> R) -> R {
        f(self.readout)
    }

    fn stop_readout(&mut self) {
        self.paused = true;
    }

    /// Nothing to do now: the device re-synchronises the readout when the stall has passed
    /// (`SimDevice::end_stall`).
    fn restart_readout(&mut self) {}

    /// The self-test and the rate monitors, as the device holds them.
    fn board_health(&self) -> BoardHealth {
        self.health
    }
}
