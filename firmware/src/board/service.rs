//! The main loop: the calibration protocol over the serial link, rate averaging, stream frames,
//! flash stores with the readout paused, and the watchdog. Everything here is preemptible and
//! nothing in an interrupt waits for it.
//!
//! Per received line: `LineAssembler` -> `strip_checksum` -> `parse` -> `Executor::execute`
//! against [`BoardLink`] (the `DeviceLink` of the board) -> exactly one answer line. This is the
//! same sequence as hal-sim's `SimDevice`, including the stream framing: while streaming, a text
//! answer is wrapped in 0x00 delimiters so the host can tell it from a COBS frame.
//!
//! The loop sleeps (`WFI`) when the RX and record queues are empty; any interrupt wakes it, at
//! the latest the 1 ms tick, which bounds the delay of a byte that arrived between the check
//! and the `WFI`.

use core::sync::atomic::{AtomicU32, Ordering};

use embedded_storage::nor_flash::NorFlash;
use heapless::spsc::Consumer;

use super::app::{self, now_ms, READOUT};
use super::usart::SerialPort;
use super::watchdog::Watchdog;
use super::{adc, turnaround, usart};
use crate::calibration::validation::AcceptanceLimits;
use crate::protocol::endpoint;
use crate::protocol::execute::{DeviceLink, DeviceStatus, Executor, Identity};
use crate::protocol::line::{LineAssembler, LineEvent, MAX_LINE};
use crate::protocol::respond::MAX_RESPONSE;
use crate::protocol::stream::{encode_frame, MAX_FRAME};
use crate::readout::{Readout, ReadoutConfig};
use crate::signal::compensation::CompensationSettings;
use crate::signal::lockin::CycleRecord;
use crate::signal::output::{AveragerConfig, AveragingMode, RateAverager};
use crate::storage::{
    CalibrationRecord, CalibrationStore, Geometry, LoadReport, ReadoutPaused, StoreError,
};

/// Stream frames dropped because the TX queue had no room (the host sees a sequence gap).
pub static FRAMES_DROPPED: AtomicU32 = AtomicU32::new(0);

/// Seconds between health logs (defmt, only when a counter changed).
const HEALTH_LOG_MS: u32 = 10_000;

/// The board-level loss counters the protocol's `status` does not carry, for the defmt log.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, defmt::Format)]
pub struct Health {
    pub turnarounds_late: u32,
    pub pickoff_implausible: u32,
    pub latches_unarmed: u32,
    pub latches_overwritten: u32,
    pub turnarounds_dropped: u32,
    pub records_dropped: u32,
    pub lissajous_block_overruns: u32,
    pub dma_errors: u32,
    pub usart_overruns: u32,
    pub usart_line_errors: u32,
    pub usart_rx_dropped: u32,
    pub frames_dropped: u32,
}

impl Health {
    pub fn now() -> Self {
        let get = |c: &AtomicU32| c.load(Ordering::Relaxed);
        Self {
            turnarounds_late: get(&turnaround::LATE),
            pickoff_implausible: get(&turnaround::IMPLAUSIBLE),
            latches_unarmed: get(&turnaround::UNARMED),
            latches_overwritten: get(&turnaround::LATCH_OVERWRITTEN),
            turnarounds_dropped: get(&app::TURNAROUNDS_DROPPED),
            records_dropped: get(&app::RECORDS_DROPPED),
            lissajous_block_overruns: get(&adc::BLOCK_OVERRUNS),
            dma_errors: get(&adc::DMA_ERRORS),
            usart_overruns: get(&usart::OVERRUNS),
            usart_line_errors: get(&usart::LINE_ERRORS),
            usart_rx_dropped: get(&usart::RX_DROPPED),
            frames_dropped: get(&FRAMES_DROPPED),
        }
    }
}

/// What differs between the board and the QEMU serial test.
#[derive(Clone, Copy)]
pub struct ServiceConfig {
    pub identity: Identity,
    /// Where the calibration store lives in `F`'s offsets.
    pub geometry: Geometry,
    /// The turnaround/Lissajous hardware runs (false in QEMU: an idle readout).
    pub hardware: bool,
    pub dither_hz: f64,
    pub scale_factor_arcsec: f64,
    /// Sent once at start, so the host knows the receiver is on (QEMU drops earlier bytes).
    pub banner: Option<&'static str>,
    /// Sees every complete line first; `true` = consumed, no answer (test hooks only).
    pub intercept: Option<fn(&str) -> bool>,
}

/// The main loop's state.
pub struct Service<F: NorFlash> {
    config: ServiceConfig,
    readout_config: ReadoutConfig,
    serial: SerialPort,
    flash: F,
    store: CalibrationStore,
    executor: Executor,
    line: LineAssembler,
    records: Consumer<'static, CycleRecord>,
    averager: RateAverager,
    averager_config: AveragerConfig,
    status: DeviceStatus,
    watchdog: Option<Watchdog>,
    health: Health,
    health_logged_ms: u32,
}

impl<F: NorFlash> Service<F> {
    /// Loads the calibration (or the defaults) from `flash` and creates the readout with it.
    /// The readout's interrupts are the caller's to unmask (see `app`).
    pub fn new(
        config: ServiceConfig,
        serial: SerialPort,
        mut flash: F,
        watchdog: Option<Watchdog>,
        readout_config: ReadoutConfig,
    ) -> Self {
        let store = CalibrationStore::new(&flash, config.geometry)
            .unwrap_or_else(|e| defmt::panic!("calibration store geometry: {}", e));
        let (record, report) = store.load(&mut flash);
        defmt::info!("calibration: {}", report);
        let readout = Readout::new(&readout_config, record.settings);
        let records = app::init_readout(readout_config, readout);
        Self {
            executor: Executor::new(
                &report,
                record.fit,
                // Boots are not counted in flash (that would wear it): the stored count + 1.
                record.boot_count.wrapping_add(1),
                AcceptanceLimits::DEFAULT,
            ),
            averager_config: AveragerConfig {
                window_cycles: libm::round(config.dither_hz).max(1.0) as u32,
                mode: AveragingMode::WholePeriods,
                timer_hz: super::TIMER_HZ as f64,
                scale_factor_arcsec: config.scale_factor_arcsec,
            },
            averager: RateAverager::new(),
            status: DeviceStatus::default(),
            line: LineAssembler::new(),
            config,
            readout_config,
            serial,
            flash,
            store,
            records,
            watchdog,
            health: Health::default(),
            health_logged_ms: now_ms(),
        }
    }

    /// The main loop.
    pub fn run(mut self) -> ! {
        if let Some(banner) = self.config.banner {
            self.send(banner.as_bytes());
            self.send(b"\r\n");
        }
        loop {
            self.refresh_watchdog();
            let mut busy = false;
            while let Some(byte) = self.serial.read_byte() {
                self.on_byte(byte);
                busy = true;
            }
            while let Some(record) = self.records.dequeue() {
                self.on_cycle(&record);
                busy = true;
            }
            self.log_health();
            if !busy {
                cortex_m::asm::wfi();
            }
        }
    }

    /// Logs the loss counters every [`HEALTH_LOG_MS`] if any changed (bring-up aid).
    fn log_health(&mut self) {
        let now = now_ms();
        if now.wrapping_sub(self.health_logged_ms) < HEALTH_LOG_MS {
            return;
        }
        self.health_logged_ms = now;
        let health = Health::now();
        if health != self.health {
            defmt::warn!("board health: {}", health);
            self.health = health;
        }
    }

    fn refresh_watchdog(&mut self) {
        if let Some(dog) = self.watchdog.as_mut() {
            dog.refresh();
        }
    }

    fn on_byte(&mut self, byte: u8) {
        // Framing follows the mode the host was in when it sent the line.
        let streaming = self.executor.streaming();
        let mut copy = heapless::String::<MAX_LINE>::new();
        let event = match self.line.push(byte) {
            None => return,
            Some(LineEvent::Line(text)) => {
                let _ = copy.push_str(text);
                if self.config.intercept.is_some_and(|hook| hook(&copy)) {
                    return;
                }
                LineEvent::Line(&copy)
            }
            Some(LineEvent::TooLong) => LineEvent::TooLong,
            Some(LineEvent::Garbage) => LineEvent::Garbage,
        };
        self.refresh_status();
        let mut link = BoardLink {
            flash: &mut self.flash,
            store: &self.store,
            status: self.status,
            hardware: self.config.hardware,
            watchdog: self.watchdog.as_mut(),
        };
        let answer = endpoint::answer(event, &mut self.executor, &self.config.identity, &mut link);
        endpoint::send_answer(streaming, &answer, |bytes| self.send(bytes));
    }

    fn on_cycle(&mut self, record: &CycleRecord) {
        let reading = self.averager.push(&self.averager_config, record.output);
        self.status.on_cycle(record.output.flags, reading);
        let cycle_s = record.duration_s(&self.readout_config.cycle);
        let actions = self.executor.on_cycle(record, cycle_s);
        if let Some(settings) = actions.stage {
            // The tracking loop's coefficients: staged like a `set`, applied at a cycle boundary.
            READOUT.lock(|task| task.readout.stage_compensation(settings));
        }
        if let Some(frame) = actions.frame {
            let mut buf = [0u8; MAX_FRAME];
            let n = encode_frame(&frame, &mut buf);
            // A frame goes out whole or not at all; answers have priority over frames.
            if self.serial.tx_room() >= n + MAX_RESPONSE {
                self.serial.write(&buf[..n]);
                self.serial.kick();
            } else {
                FRAMES_DROPPED.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// Queues all of `bytes`, waiting for room (the USART handler drains the queue).
    fn send(&mut self, mut bytes: &[u8]) {
        while !bytes.is_empty() {
            let n = self.serial.write(bytes);
            bytes = &bytes[n..];
            self.serial.kick();
            if !bytes.is_empty() {
                self.refresh_watchdog();
                cortex_m::asm::wfi();
            }
        }
    }

    fn refresh_status(&mut self) {
        let Some((counters, (amplitude, hz))) =
            READOUT.lock(|task| (task.readout.counters(), task.readout.dither()))
        else {
            return;
        };
        self.status.update_from(&counters, (amplitude, hz));
        // Hardware-level losses count as missed turnarounds too.
        let hardware_missed = turnaround::LATE.load(Ordering::Relaxed)
            + app::TURNAROUNDS_DROPPED.load(Ordering::Relaxed);
        self.status.missed_turnarounds = self.status.missed_turnarounds.max(hardware_missed);
    }
}

/// The firmware's view of the board during one command.
pub struct BoardLink<'a, F> {
    flash: &'a mut F,
    store: &'a CalibrationStore,
    status: DeviceStatus,
    hardware: bool,
    watchdog: Option<&'a mut Watchdog>,
}

impl<F: NorFlash> DeviceLink for BoardLink<'_, F> {
    type FlashError = F::Error;

    fn now_ms(&self) -> u32 {
        now_ms()
    }

    fn status(&self) -> DeviceStatus {
        self.status
    }

    fn active_settings(&self) -> CompensationSettings {
        READOUT
            .lock(|task| task.readout.staged_or_active_compensation())
            .unwrap_or_default()
    }

    fn stage_settings(&mut self, settings: CompensationSettings) {
        READOUT.lock(|task| task.readout.stage_compensation(settings));
    }

    /// Pauses the readout (its interrupts masked, the sample queue drained), stores with the
    /// watchdog refreshed on both sides of the stall, and resumes re-synchronised.
    fn store(&mut self, record: &CalibrationRecord) -> Result<u32, StoreError<F::Error>> {
        app::pause_readout(self.hardware);
        // The token lives exactly as long as the readout is paused.
        let paused = ReadoutPaused::assume_paused();
        if let Some(dog) = self.watchdog.as_mut() {
            dog.refresh();
        }
        let result = self.store.store_while_paused(self.flash, &paused, record);
        if let Some(dog) = self.watchdog.as_mut() {
            dog.refresh();
        }
        app::resume_readout(self.hardware);
        result
    }

    fn load(&mut self) -> (CalibrationRecord, LoadReport) {
        self.store.load(self.flash)
    }
}
