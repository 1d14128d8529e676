//! The command service: the one piece of glue between the serial protocol, the binary stream,
//! the calibration store and the readout, for the board and the simulated board alike.
//!
//! Two events drive it, from whatever loop the platform runs:
//! - [`Service::on_byte`], every received byte: `LineAssembler` -> `strip_checksum` -> `parse`
//!   -> `Executor::execute` against the device -> exactly one answer line (`protocol::endpoint`);
//!   while streaming, a text answer is wrapped in 0x00 delimiters so the host can tell it from a
//!   COBS frame;
//! - [`Service::on_cycle`], every dither cycle the readout closed: the averaged rate and flags
//!   for `status`, a running calibration and the tracking loop (whose coefficients are staged
//!   into the readout), and a stream frame (queued whole or dropped and counted).
//!
//! Everything that differs between the board and the simulator is behind the small traits of
//! [`ports`] (clock, serial transmitter, readout access, dither access, the key's OTP) and `embedded_storage`'s
//! `NorFlash`
//! (the calibration flash, owned by the service). The board's main loop (`board::app`) and
//! hal-sim's `SimDevice` each instantiate this one `Service`; neither has protocol glue of its
//! own. A flash store pauses the readout through [`ports::pause`], whose guard is the pause.
//!
//! Sans-IO: nothing here blocks except [`ports::SerialTx::send`] waiting for queue room, and
//! nothing touches a register. It builds and is tested on the host.

// Input from outside the board passes here: integer arithmetic is checked, wrapping or
// saturating where an input could overflow it (the crate denies the panicking calls,
// `lib.rs`; each exception is allowed where it stands, with its reason).
#![cfg_attr(not(test), deny(clippy::arithmetic_side_effects))]

pub mod ports;
pub mod power_up;
pub mod record_queue;

use embedded_storage::nor_flash::NorFlash;
use heapless::String;

use crate::calibration::validation::AcceptanceLimits;
use crate::dither::{CommandError, DitherStatus};
use crate::profile::BoardProfile;
use crate::protocol::endpoint;
use crate::protocol::execute::{DeviceLink, DeviceStatus, Executor, Identity};
use crate::protocol::key::Key;
use crate::protocol::line::{LineAssembler, LineEvent, MAX_LINE};
use crate::protocol::link::KeyWriteError;
use crate::protocol::output_frame::{encode_output_frame, MAX_OUTPUT_FRAME};
use crate::protocol::stream::{encode_frame, MAX_FRAME};
use crate::protocol::thermal_frame::{encode_thermal_frame, THERMAL_FRAME};
use crate::readout::ReadoutConfig;
use crate::signal::compensation::CompensationSettings;
use crate::signal::lockin::CycleRecord;
use crate::signal::output::record::OutputRecord;
use crate::signal::output::{AveragerConfig, AveragingMode, RateAverager};
use crate::storage::{
    CalibrationRecord, CalibrationStore, DitherSetpoints, Geometry, GeometryError, LoadReport,
    StoreError, Stored, StripCoefficients,
};
use crate::thermal::model::ThermalModel;
use crate::thermal::sensor::SensorUpdate;
use crate::thermal::state::ThermalState;
use ports::{Clock, DitherAccess, ReadoutAccess, Secrets, SerialTx};

/// Lines a main-loop pass executes at most ([`Service::pass`]).
pub const LINES_PER_PASS: usize = 1;
/// Cycle records a main-loop pass takes at most: the board's whole record queue.
pub const RECORDS_PER_PASS: usize = 32;
/// Output records a main-loop pass takes at most: the board's whole output record queue.
pub const OUTPUTS_PER_PASS: usize = 64;

/// What differs between services (immutable).
#[derive(Clone, Copy, Debug)]
pub struct ServiceConfig {
    /// What `id` reports; the unlock key.
    pub identity: Identity,
    /// Where the calibration store lives in the flash's offsets.
    pub geometry: Geometry,
    /// The readout's settings (the cycle durations' timer).
    pub readout: ReadoutConfig,
    /// The averaged rate `status` reports.
    pub rate_output: AveragerConfig,
    /// Sees every complete line first; `true` = consumed, no answer (test hooks only).
    pub intercept: Option<fn(&str) -> bool>,
}

impl ServiceConfig {
    /// The settings for a board of `profile` with a dither near `dither_hz`: the rate averaged
    /// over whole output periods of about one second.
    pub fn for_profile(
        profile: &BoardProfile,
        dither_hz: f64,
        identity: Identity,
        geometry: Geometry,
    ) -> Self {
        Self {
            identity,
            geometry,
            readout: profile.readout_config(dither_hz),
            rate_output: AveragerConfig {
                window_cycles: libm::round(dither_hz).max(1.0) as u32,
                mode: AveragingMode::WholePeriods,
                timer_hz: profile.timer_hz as f64,
                scale_factor_arcsec: profile.scale_factor_arcsec,
            },
            intercept: None,
        }
    }
}

/// A service just booted: the settings its readout and its dither drive must start with, and
/// what the load found.
pub struct Booted<F: NorFlash> {
    /// The service, locked, owning the flash.
    pub service: Service<F>,
    /// The compensation settings loaded from flash (or the defaults).
    pub settings: CompensationSettings,
    /// The dither drive's stored setpoints; `None`: the drive keeps its defaults.
    pub dither: Option<DitherSetpoints>,
    /// The stored stripping coefficients; `None`: the profile's nominal K (the fit learns it).
    pub strip: Option<StripCoefficients>,
    /// What the load found: loaded or defaults (and why), and the store's health.
    pub report: LoadReport,
}

/// The command service (see the module docs).
pub struct Service<F: NorFlash> {
    config: ServiceConfig,
    flash: F,
    store: CalibrationStore,
    executor: Executor,
    line: LineAssembler,
    averager: RateAverager,
    status: DeviceStatus,
    frames_dropped: u32,
    /// The wrong-key count last handed to [`Secrets::save_wrong_keys`].
    saved_wrong_keys: u32,
    /// The block's temperature, its rate and the thermal model (`crate::thermal`).
    thermal: ThermalState,
}

impl<F: NorFlash> Service<F> {
    /// Powers up: loads the newest valid calibration from `flash` (or the defaults), locked.
    /// `boot_count`: the boots so far, or `None` for the stored count + 1 (boots are not written
    /// to flash: that would wear it).
    pub fn boot(
        config: ServiceConfig,
        mut flash: F,
        boot_count: Option<u32>,
    ) -> Result<Booted<F>, GeometryError> {
        let store = CalibrationStore::new(&flash, config.geometry)?;
        let (record, report) = store.load_for_serial(&mut flash, config.identity.serial_number);
        // Saturating: a counter never wraps in the field.
        let boots = boot_count.unwrap_or(record.boot_count.saturating_add(1));
        let mut thermal = ThermalState::new();
        if let Some(stored) = record.thermal {
            let sf = config.readout.output.scale_factor_arcsec;
            thermal.set_model(Some(stored.model), stored.enabled, sf);
        }
        let service = Self {
            executor: Executor::new(&report, record.fit, boots, AcceptanceLimits::DEFAULT),
            line: LineAssembler::new(),
            averager: RateAverager::new(),
            status: DeviceStatus::default(),
            frames_dropped: 0,
            saved_wrong_keys: 0,
            thermal,
            config,
            flash,
            store,
        };
        Ok(Booted {
            service,
            settings: record.settings,
            dither: record.dither,
            strip: record.strip,
            report,
        })
    }

    /// Right after boot: the wrong-key count the platform kept across the reset (0 when its
    /// memory was lost); past the free attempts, the unlock windows are counted from `now_ms`.
    pub fn restore_wrong_keys(&mut self, wrong_keys: u32, now_ms: u64) {
        self.executor.restore_wrong_keys(wrong_keys, now_ms);
        self.saved_wrong_keys = wrong_keys;
    }

    /// A new client on the link (the simulated board served over TCP: a new connection):
    /// locked, no stream, an empty line buffer ([`Executor::new_session`]).
    pub fn new_session(&mut self) {
        self.executor.new_session();
        self.line = LineAssembler::new();
    }

    /// One main-loop pass with bounded work: bytes from `read_byte` until at most
    /// [`LINES_PER_PASS`] lines were executed, then at most [`OUTPUTS_PER_PASS`] output records
    /// from `next_output` and [`RECORDS_PER_PASS`] cycle records from `next_record`, each after
    /// the cycles lost right before it ([`record_queue`]: the stream's gap stands where they
    /// were). Returns whether anything was done (more may be waiting: the caller runs another
    /// pass before it sleeps). The bound keeps a pass short whatever the host
    /// sends, so the board's main loop refreshes its watchdog between any two commands (a
    /// flood of `reload`, each a scan of both flash sectors, cannot starve it).
    pub fn pass<P: Clock + SerialTx + ReadoutAccess + DitherAccess + Secrets>(
        &mut self,
        ports: &mut P,
        mut read_byte: impl FnMut(&mut P) -> Option<u8>,
        mut next_record: impl FnMut() -> Option<record_queue::Tagged<CycleRecord>>,
        mut next_output: impl FnMut() -> Option<OutputRecord>,
    ) -> bool {
        let mut busy = false;
        let mut lines = 0;
        while lines < LINES_PER_PASS {
            let Some(byte) = read_byte(ports) else {
                break;
            };
            busy = true;
            lines = lines.saturating_add(usize::from(self.on_byte(byte, ports)));
        }
        for _ in 0..OUTPUTS_PER_PASS {
            let Some(record) = next_output() else {
                break;
            };
            self.on_output(&record, ports);
            busy = true;
        }
        for _ in 0..RECORDS_PER_PASS {
            let Some(tagged) = next_record() else {
                break;
            };
            if tagged.lost_before > 0 {
                self.on_cycles_lost(tagged.lost_before);
            }
            self.on_cycle(&tagged.record, ports);
            busy = true;
        }
        busy
    }

    /// One received byte; a completed line is executed and answered through `ports`. Returns
    /// whether the byte completed a line (a command executed, or a line refused).
    pub fn on_byte<P: Clock + SerialTx + ReadoutAccess + DitherAccess + Secrets>(
        &mut self,
        byte: u8,
        ports: &mut P,
    ) -> bool {
        // Framing: an answer is wrapped in 0x00 when a stream is on before or after the line
        // (`endpoint::send_answer`).
        let streaming_before = self.executor.streaming();
        let mut line = String::<MAX_LINE>::new();
        let event = match self.line.push(byte) {
            None => return false,
            Some(LineEvent::Line(text)) => {
                // The assembler is borrowed by `text`: copy (at most MAX_LINE bytes).
                let _ = line.push_str(text);
                if self.config.intercept.is_some_and(|hook| hook(&line)) {
                    return true;
                }
                LineEvent::Line(&line)
            }
            Some(LineEvent::TooLong) => LineEvent::TooLong,
            Some(LineEvent::Garbage) => LineEvent::Garbage,
        };
        self.refresh_status(ports);
        let mut device = ServiceDevice {
            flash: &mut self.flash,
            readout: &self.config.readout,
            store: &self.store,
            serial_number: self.config.identity.serial_number,
            status: self.status,
            thermal: &mut self.thermal,
            ports,
        };
        let answer = endpoint::answer(
            event,
            &mut self.executor,
            &self.config.identity,
            &mut device,
        );
        // Kept before the answer goes out: a reset right after a wrong key still counts it.
        let wrong_keys = self.executor.wrong_keys();
        if wrong_keys != self.saved_wrong_keys {
            ports.save_wrong_keys(wrong_keys);
            self.saved_wrong_keys = wrong_keys;
        }
        let wrapped = streaming_before || self.executor.streaming();
        endpoint::send_answer(wrapped, &answer, |bytes| ports.send(bytes));
        true
    }

    /// `n` closed cycles were lost on the way to the service (the board's record queue was
    /// full): counted (`status`: `dropped=`), and the stream leaves a sequence gap for the
    /// frames they were due, so no loss is silent.
    pub fn on_cycles_lost(&mut self, n: u32) {
        self.status.cycles_dropped = self.status.cycles_dropped.saturating_add(n);
        self.executor.on_cycles_lost(n);
    }

    /// One dither cycle the readout closed.
    pub fn on_cycle<P: SerialTx + ReadoutAccess>(&mut self, record: &CycleRecord, ports: &mut P) {
        let reading = self.averager.push(&self.config.rate_output, record.output);
        self.status.on_cycle(record.output.flags, reading);
        let cycle_s = record.duration_s(&self.config.readout.cycle);
        let actions = self.executor.on_cycle(record, cycle_s);
        if let Some(settings) = actions.stage {
            // The tracking loop's coefficients: staged like a `set`, applied at a cycle boundary.
            ports.with_readout(|readout| readout.stage_compensation(settings));
        }
        if let Some(frame) = actions.frame {
            let mut buf = [0u8; MAX_FRAME];
            let n = encode_frame(&frame, &mut buf);
            if !ports.try_send_frame(buf.get(..n).unwrap_or(&buf)) {
                self.frames_dropped = self.frames_dropped.saturating_add(1);
            }
        }
    }

    /// One fixed-rate output record: sent as a frame when the output is streamed (`stream
    /// output`), queued whole or dropped and counted; a dropped record shows to the host as a
    /// gap in the records' own sequence numbers.
    ///
    /// A thermal frame goes first when the record's temperature or rate is new to the host
    /// (`protocol::thermal_frame`); when it finds no room the record is dropped too (it would
    /// find none either) and the next record gets the thermal frame.
    pub fn on_output<P: SerialTx>(&mut self, record: &OutputRecord, ports: &mut P) {
        let Some(out) = self.executor.on_output(record) else {
            return;
        };
        if let Some(thermal) = out.thermal {
            let mut buf = [0u8; THERMAL_FRAME];
            let n = encode_thermal_frame(&thermal, &mut buf);
            if !ports.try_send_frame(buf.get(..n).unwrap_or(&buf)) {
                self.executor.thermal_frame_lost();
                self.frames_dropped = self.frames_dropped.saturating_add(1);
                return;
            }
        }
        let mut buf = [0u8; MAX_OUTPUT_FRAME];
        let n = encode_output_frame(&out.record, &mut buf);
        if !ports.try_send_frame(buf.get(..n).unwrap_or(&buf)) {
            self.frames_dropped = self.frames_dropped.saturating_add(1);
        }
    }

    /// What the temperature sensor's monitor found (the main loop polls it,
    /// `thermal::sensor::SensorMonitor::poll`): the thermal state follows, and the output
    /// stage gets the temperature, its rate and the correction for its next records.
    pub fn on_sensor<P: ReadoutAccess>(&mut self, update: SensorUpdate, ports: &mut P) {
        let sf = self.config.readout.output.scale_factor_arcsec;
        let input = self.thermal.on_sensor(update, sf);
        ports.with_readout(|r| r.set_thermal(input));
    }

    /// The thermal state.
    pub fn thermal(&self) -> &ThermalState {
        &self.thermal
    }

    /// Whether the binary stream is on.
    pub fn streaming(&self) -> bool {
        self.executor.streaming()
    }

    /// Stream frames dropped because the transmitter had no room (the host sees sequence gaps).
    pub fn frames_dropped(&self) -> u32 {
        self.frames_dropped
    }

    /// The settings the service runs with.
    pub fn config(&self) -> &ServiceConfig {
        &self.config
    }

    /// The calibration flash.
    pub fn flash(&self) -> &F {
        &self.flash
    }

    /// The calibration flash (e.g. a simulated one, to arm a power cut).
    pub fn flash_mut(&mut self) -> &mut F {
        &mut self.flash
    }

    /// Ends the service and hands back its flash (power off: the contents survive).
    pub fn into_flash(self) -> F {
        self.flash
    }

    fn refresh_status<P: ReadoutAccess>(&mut self, ports: &mut P) {
        let config = &self.config.readout;
        let (counters, dither, strip, records) = ports.with_readout(|r| {
            (
                r.counters(),
                r.dither(),
                r.strip_status(config),
                r.output_records(),
            )
        });
        self.status.update_from(&counters, dither);
        self.status.strip = strip;
        self.status.output_records = records;
        self.status.missed_turnarounds = self
            .status
            .missed_turnarounds
            .max(ports.missed_below_readout());
    }
}

/// The device as the protocol sees it during one command: the service's flash and store, a
/// status snapshot, and the platform's ports.
struct ServiceDevice<'a, F, P> {
    flash: &'a mut F,
    readout: &'a ReadoutConfig,
    store: &'a CalibrationStore,
    /// This board's gyro: records of another are not loaded.
    serial_number: u32,
    status: DeviceStatus,
    thermal: &'a mut ThermalState,
    ports: &'a mut P,
}

impl<F: NorFlash, P: Clock + ReadoutAccess + DitherAccess + Secrets> DeviceLink
    for ServiceDevice<'_, F, P>
{
    type FlashError = F::Error;

    fn now_ms(&self) -> u64 {
        self.ports.now_ms()
    }

    fn status(&self) -> DeviceStatus {
        self.status
    }

    fn active_settings(&mut self) -> CompensationSettings {
        self.ports
            .with_readout(|readout| readout.staged_or_active_compensation())
    }

    fn stage_settings(&mut self, settings: CompensationSettings) {
        self.ports
            .with_readout(|readout| readout.stage_compensation(settings));
    }

    /// Stores, with the readout paused from right before a sector erase to the end of the
    /// store (the guard's lifetime), and not at all without an erase.
    fn store(&mut self, record: &CalibrationRecord) -> Result<Stored, StoreError<F::Error>> {
        let ports = &mut *self.ports;
        self.store.store(self.flash, record, || ports::pause(ports))
    }

    fn load(&mut self) -> (CalibrationRecord, LoadReport) {
        self.store.load_for_serial(self.flash, self.serial_number)
    }

    fn dither_status(&mut self) -> DitherStatus {
        self.ports.with_dither(|drive, config| drive.status(config))
    }

    fn dither_setpoints(&mut self) -> DitherSetpoints {
        self.ports.with_dither(|drive, _| drive.setpoints())
    }

    fn apply_dither(&mut self, setpoints: DitherSetpoints) -> Result<(), CommandError> {
        self.ports
            .with_dither(|drive, config| drive.apply_setpoints(config, setpoints))
    }

    fn strip_coefficients(&mut self) -> Option<StripCoefficients> {
        let config = self.readout;
        let status = self.ports.with_readout(|r| r.strip_status(config));
        if !status.converged {
            return None;
        }
        StripCoefficients::from_fringes_per_code(status.k, status.k_quadrature)
    }

    fn apply_strip(&mut self, strip: StripCoefficients) {
        let config = self.readout;
        self.ports
            .with_readout(|r| r.restart_strip_from(config, strip.k(), strip.k_quadrature()));
    }

    fn program_key(&mut self, key: &Key) -> Result<(), KeyWriteError> {
        self.ports.program_key(key)
    }

    fn thermal(&mut self) -> ThermalState {
        *self.thermal
    }

    fn set_thermal_model(&mut self, model: Option<ThermalModel>, enabled: bool) {
        let sf = self.readout.output.scale_factor_arcsec;
        let input = self.thermal.set_model(model, enabled, sf);
        self.ports.with_readout(|r| r.set_thermal(input));
    }

    fn thermal_scale_factor_arcsec(&mut self) -> f32 {
        self.readout.output.scale_factor_arcsec
    }

    fn board_health(&mut self) -> crate::board_timing::health::BoardHealth {
        let pickoff = self.ports.with_dither(|drive, _| drive.pickoff_check());
        let mut health = self.ports.board_health();
        health.selftest = health.selftest.with_pickoff(pickoff);
        health
    }
}

#[cfg(test)]
mod tests;
