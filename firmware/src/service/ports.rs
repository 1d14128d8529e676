//! What the command service needs from the platform it runs on: five small traits, and the
//! readout pause as a guard.
//!
//! The board implements them on its peripherals (`board::ports`: SysTick, the USART queues, the
//! readout task's priority lock and interrupt masks); hal-sim's simulated device implements them
//! on plain memory (simulated time, an output buffer, the `Readout` it steps). The flash is the
//! fourth difference and needs no trait of ours: it is `embedded_storage`'s `NorFlash`.
//!
//! # The pause: one source
//! A flash store stalls the CPU (storage module docs), so the readout must be stopped before and
//! re-synchronised after. [`ReadoutPause`] is the only way the service gets the storage's
//! [`ReadoutPaused`] token: [`pause`] stops the readout and returns the guard, dropping the guard
//! restarts it. The pause therefore lasts exactly as long as the guard lives, and no path can
//! store without stopping the readout or forget to restart it (an early return included).

use crate::dither::{DitherConfig, DitherController};
use crate::protocol::key::Key;
use crate::protocol::link::KeyWriteError;
use crate::readout::Readout;
use crate::storage::ReadoutPaused;

/// A millisecond clock.
pub trait Clock {
    /// Milliseconds since start: monotonic, 64 bits, never wraps (the protocol's unlock and
    /// window times compare plainly).
    fn now_ms(&self) -> u64;
}

/// The serial transmitter.
pub trait SerialTx {
    /// Queues all of `bytes` (an answer): waits for room if it must, never drops.
    fn send(&mut self, bytes: &[u8]);
    /// Queues a stream frame whole, if it fits now beside the room an answer needs; returns
    /// false (and queues nothing) otherwise. A dropped frame shows to the host as a sequence gap.
    fn try_send_frame(&mut self, frame: &[u8]) -> bool;
}

/// The service's access to the readout, which runs in its own (higher-priority) context.
pub trait ReadoutAccess {
    /// Runs `f` on the readout, excluding the readout's own context meanwhile.
    fn with_readout<R>(&mut self, f: impl FnOnce(&mut Readout) -> R) -> R;
    /// Stops the readout: no sample reaches it until [`Self::restart_readout`]. Only [`pause`]
    /// calls it.
    fn stop_readout(&mut self);
    /// Starts the readout again, re-synchronised (`Readout::resynchronise`) once the stall is
    /// over. Only the guard's drop calls it.
    fn restart_readout(&mut self);
    /// Turnarounds lost below the readout (hardware queues, late schedules); `status` reports
    /// the larger of this and the readout's own count.
    fn missed_below_readout(&self) -> u32 {
        0
    }
    /// The board's power-up self-test (its pick-off check is the dither controller's, which
    /// the service adds) and the rate monitors' faults; a platform without a board: untested.
    fn board_health(&self) -> crate::board_timing::health::BoardHealth {
        crate::board_timing::health::BoardHealth::UNTESTED
    }
}

/// The service's access to the dither drive's controller, which runs in the drive tick's
/// (higher-priority) context.
pub trait DitherAccess {
    /// Runs `f` on the controller and its configuration, excluding the drive tick meanwhile.
    fn with_dither<R>(&mut self, f: impl FnOnce(&mut DitherController, &DitherConfig) -> R) -> R;
}

/// The board's security memory: the one-time-programmable key (`key provision`) and the
/// wrong-key count that must survive a reset.
pub trait Secrets {
    /// Writes `key` to OTP and locks the block; `Err` leaves the board unprovisioned.
    fn program_key(&mut self, key: &Key) -> Result<(), KeyWriteError>;
    /// Keeps the wrong-key count across resets (backup RAM on the board: no wear). Called only
    /// when the count changed, so at most once per `unlock` attempt, and attempts are
    /// throttled by the unlock windows. The platform reads it back at boot for
    /// `Service::restore_wrong_keys`.
    fn save_wrong_keys(&mut self, count: u32);
}

/// The readout stopped for as long as this guard lives (see the module docs).
pub struct ReadoutPause<'a, R: ReadoutAccess> {
    access: &'a mut R,
    token: ReadoutPaused,
}

/// Stops the readout; it restarts when the returned guard is dropped.
pub fn pause<R: ReadoutAccess>(access: &mut R) -> ReadoutPause<'_, R> {
    access.stop_readout();
    ReadoutPause {
        access,
        token: ReadoutPaused::assume_paused(),
    }
}

impl<R: ReadoutAccess> ReadoutPause<'_, R> {
    /// The storage's token: proof, for `CalibrationStore::store_while_paused`, that the readout
    /// is stopped.
    pub fn token(&self) -> &ReadoutPaused {
        &self.token
    }
}

impl<R: ReadoutAccess> Drop for ReadoutPause<'_, R> {
    fn drop(&mut self) {
        self.access.restart_readout();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::signal::compensation::CompensationSettings;

    struct Probe {
        readout: Readout,
        log: [u8; 4],
        n: usize,
    }

    impl ReadoutAccess for Probe {
        fn with_readout<R>(&mut self, f: impl FnOnce(&mut Readout) -> R) -> R {
            f(&mut self.readout)
        }
        fn stop_readout(&mut self) {
            self.log[self.n] = b's';
            self.n += 1;
        }
        fn restart_readout(&mut self) {
            self.log[self.n] = b'r';
            self.n += 1;
        }
    }

    fn stop_store_fail() -> Result<(), ()> {
        Err(())
    }

    #[test]
    fn the_guard_stops_once_and_restarts_on_every_exit() {
        let config = crate::profile::BoardProfile::F405.readout_config(389.0);
        let mut probe = Probe {
            readout: Readout::new(&config, CompensationSettings::default()),
            log: [0; 4],
            n: 0,
        };
        let result = (|| {
            let guard = pause(&mut probe);
            let _ = guard.token();
            stop_store_fail()?; // an early return still restarts
            Ok::<(), ()>(())
        })();
        assert!(result.is_err());
        assert_eq!(&probe.log[..probe.n], b"sr");
        drop(pause(&mut probe));
        assert_eq!(&probe.log[..probe.n], b"srsr");
    }
}
