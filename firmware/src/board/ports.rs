//! The board's side of the command service's ports (`crate::service::ports`): the SysTick
//! clock, the USART1 transmit queue, the readout behind its lock, stopped for a flash store by
//! masking the readout interrupts, the dither controller behind the drive tick's lock, and the
//! key's OTP block. The locks are the board's statics (`resources::STATIC_LOCKS`: priority
//! locks and the latch plan's critical section) or, in `examples/rtic_board.rs`, RTIC's
//! resource proxies ([`BoardPorts::with_locks`]).
//!
//! The watchdog lives here too: the service may wait (a full TX queue, a flash stall), and every
//! wait refreshes it, so the main loop's own refresh is not the only one.

use core::sync::atomic::Ordering;

use super::resources::{
    self, DitherLock, DitherTask, Locks, ReadoutLock, ReadoutTask, STATIC_LOCKS,
    TURNAROUNDS_DROPPED,
};
use super::turnaround::{self, PlanLock};
use super::usart::SerialPort;
use super::watch::Watch;
use super::watchdog::Watchdog;
use super::Shared;
use crate::board_timing::health::BoardHealth;
use crate::board_timing::selftest::SelfTestReport;
use crate::dither::{DitherConfig, DitherController};
use crate::protocol::key::Key;
use crate::protocol::link::KeyWriteError;
use crate::protocol::respond::MAX_RESPONSE;
use crate::readout::Readout;
use crate::service::ports::{Clock, DitherAccess, ReadoutAccess, Secrets, SerialTx};
use crate::signal::output::latch_plan::LatchPlan;

/// What the main loop hands the service; `R`, `D` and `P` reach the readout, the dither
/// controller and the latch plan (by default the board's statics).
pub struct BoardPorts<R = ReadoutLock, D = DitherLock, P = PlanLock> {
    /// The main loop's side of USART1, the protocol's serial link.
    pub serial: SerialPort,
    /// The IWDG, refreshed every loop pass and every wait (`None`: no watchdog).
    pub watchdog: Option<Watchdog>,
    /// The turnaround and Lissajous hardware runs (false in the QEMU serial test: an idle
    /// readout, only its task and lock exist).
    pub hardware: bool,
    /// The power-up self-test's clock, timer and trigger checks.
    pub selftest: SelfTestReport,
    /// The rate monitors (run only with the hardware).
    pub watch: Watch,
    /// The values the main loop shares with the handlers.
    pub locks: Locks<R, D, P>,
}

impl BoardPorts {
    /// The ports of a board (`hardware`) or of the serial-only QEMU example, with the power-up
    /// self-test's report, on the board's statics.
    pub fn new(
        serial: SerialPort,
        watchdog: Option<Watchdog>,
        hardware: bool,
        selftest: SelfTestReport,
    ) -> Self {
        Self::with_locks(serial, watchdog, hardware, selftest, STATIC_LOCKS)
    }
}

impl<R, D, P> BoardPorts<R, D, P> {
    /// [`BoardPorts::new`] on other locks.
    pub fn with_locks(
        serial: SerialPort,
        watchdog: Option<Watchdog>,
        hardware: bool,
        selftest: SelfTestReport,
        locks: Locks<R, D, P>,
    ) -> Self {
        Self {
            serial,
            watchdog,
            hardware,
            selftest,
            watch: Watch::new(),
            locks,
        }
    }

    /// Refreshes the watchdog, if one runs.
    pub fn refresh_watchdog(&mut self) {
        if let Some(dog) = self.watchdog.as_mut() {
            dog.refresh();
        }
    }
}

impl<R, D: Shared<Value = DitherTask>, P> BoardPorts<R, D, P> {
    /// The rate monitors' pass (every main-loop pass; nothing without the hardware).
    pub fn watch_pass(&mut self) {
        if self.hardware {
            self.watch.pass(resources::now_ms(), &mut self.locks.dither);
        }
    }
}

impl<R, D, P> Clock for BoardPorts<R, D, P> {
    fn now_ms(&self) -> u64 {
        resources::now_ms()
    }
}

impl<R, D, P> SerialTx for BoardPorts<R, D, P> {
    /// Queues all of `bytes`, sleeping until the USART handler drains room.
    fn send(&mut self, mut bytes: &[u8]) {
        while !bytes.is_empty() {
            let n = self.serial.write(bytes);
            bytes = bytes.get(n..).unwrap_or_default();
            self.serial.kick();
            if !bytes.is_empty() {
                self.refresh_watchdog();
                cortex_m::asm::wfi();
            }
        }
    }

    /// A frame goes out whole or not at all; answers have priority (room for one is kept).
    fn try_send_frame(&mut self, frame: &[u8]) -> bool {
        if self.serial.tx_room() < frame.len() + MAX_RESPONSE {
            return false;
        }
        self.serial.write(frame);
        self.serial.kick();
        true
    }
}

impl<R, D, P> ReadoutAccess for BoardPorts<R, D, P>
where
    R: Shared<Value = ReadoutTask>,
    P: Shared<Value = LatchPlan>,
{
    /// Under the readout task's priority lock (BASEPRI at its ceiling for the few instructions
    /// `f` takes). The readout exists from `resources::init_readout` on, before the main loop.
    fn with_readout<T>(&mut self, f: impl FnOnce(&mut Readout) -> T) -> T {
        self.locks
            .readout
            .lock(|task| f(&mut task.readout))
            .unwrap_or_else(|| defmt::panic!("readout used before init_readout"))
    }

    /// Masks the readout interrupts and drains the sample queue; the watchdog is refreshed
    /// right before the flash stall.
    fn stop_readout(&mut self) {
        resources::pause_readout(self.hardware, &mut self.locks.plan);
        self.refresh_watchdog();
    }

    /// Refreshes the watchdog right after the stall, re-synchronises and unmasks; the rate
    /// monitors start afresh (the events stopped on purpose).
    fn restart_readout(&mut self) {
        self.refresh_watchdog();
        resources::resume_readout(self.hardware, &mut self.locks.readout);
        self.watch.restart();
    }

    /// Turnarounds the hardware path lost: scheduled too late, or dropped from a full queue.
    fn missed_below_readout(&self) -> u32 {
        turnaround::LATE.load(Ordering::Relaxed) + TURNAROUNDS_DROPPED.load(Ordering::Relaxed)
    }

    /// The self-test's report and the watch's faults; under QEMU the self-test says which
    /// checks the emulator cannot pass.
    fn board_health(&self) -> BoardHealth {
        BoardHealth {
            selftest: self.selftest,
            timing: self.watch.faults(),
            emulated: self.hardware && cfg!(feature = "qemu"),
        }
    }
}

impl<R, D, P> Secrets for BoardPorts<R, D, P> {
    /// OTP block 0 ([`super::otp`]); the watchdog is refreshed around the few programming
    /// stalls (16 us per word).
    fn program_key(&mut self, key: &Key) -> Result<(), KeyWriteError> {
        self.refresh_watchdog();
        let result = super::otp::program_key(key);
        self.refresh_watchdog();
        result
    }

    /// Backup SRAM ([`super::backup`]).
    fn save_wrong_keys(&mut self, count: u32) {
        super::backup::save_wrong_keys(count);
    }
}

impl<R, D: Shared<Value = DitherTask>, P> DitherAccess for BoardPorts<R, D, P> {
    /// Under the drive tick's priority lock (BASEPRI at its ceiling; only the turnaround latch
    /// stays unmasked). The controller exists from `resources::start_dither` on, before the
    /// main loop.
    fn with_dither<T>(&mut self, f: impl FnOnce(&mut DitherController, &DitherConfig) -> T) -> T {
        self.locks
            .dither
            .lock(|task| f(&mut task.controller, &task.config))
            .unwrap_or_else(|| defmt::panic!("dither used before start_dither"))
    }
}
