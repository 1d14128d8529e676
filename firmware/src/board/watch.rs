//! The main loop's side of the rate monitors (`crate::board_timing::monitor`): the handlers'
//! event counts, the rates expected now, and what a raised fault does.
//!
//! Every pass of the main loop (at least once a millisecond: SysTick wakes it) reads the five
//! counters the handlers increment (photodiode DMA halves, drive ticks, turnaround latches,
//! output latches, sync edges) and hands them to the watch with the expected rates: the
//! Lissajous blocks' 48.2 Hz, the 40 kHz drive tick, twice the locked drive's frequency for
//! the turnarounds (none expected while it is not locked), the sync's rate for the latches and
//! the edges. A raised fault
//! - marks every output record `TIMING_FAULT` (invalid, the angle held) while it lasts
//!   ([`TIMING_FAULT`], read by the readout task), and `status` names it (`board=`);
//! - if it is the drive tick's or the lost clock, also takes the drive off by software
//!   (`super::dither::force_mid`: nothing else would move the DAC off its last code) and
//!   inhibits it until a reset.
//!
//! A flash store stops the events on purpose: the ports restart the watch after it.

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use super::resources::DitherTask;
use super::{adc, clocks, dither, pac, sync, turnaround, Shared};
use crate::board_timing::monitor::{Event, TimingFaults, TimingWatch};
use crate::dither::DitherState;
use crate::profile::BoardProfile;

/// A timing fault is raised: the readout task marks every output record.
pub static TIMING_FAULT: AtomicBool = AtomicBool::new(false);

/// The photodiode stream's blocks per second: TIM3's rate over a half buffer.
fn lissajous_blocks_hz() -> f32 {
    super::TIMER_HZ as f32 / (adc::TIM3_ARR + 1) as f32 / adc::BLOCK_PAIRS as f32
}

/// The main loop's watch.
#[derive(Default)]
pub struct Watch {
    watch: TimingWatch,
    drive_taken_off: bool,
}

impl Watch {
    /// Nothing watched yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// One main-loop pass at `now_ms`; `dither` is the drive tick's controller.
    pub fn pass(&mut self, now_ms: u64, dither: &mut impl Shared<Value = DitherTask>) {
        let get = |c: &AtomicU32| c.load(Ordering::Relaxed);
        let counts = [
            get(&adc::HALVES),
            get(&dither::TICKS),
            get(&turnaround::TURNAROUNDS_LATCHED),
            get(&turnaround::OUTPUTS_LATCHED),
            get(&sync::EDGES),
        ];
        let locked_hz = dither
            .lock(|task| {
                (task.controller.state() == DitherState::Locked)
                    .then(|| task.controller.estimate().frequency_hz)
            })
            .flatten();
        let sync_hz = sync::nominal_hz();
        let expected = [
            Some(lissajous_blocks_hz()),
            Some(BoardProfile::F405.drive_tick_hz as f32),
            locked_hz.map(|hz| 2.0 * hz),
            Some(sync_hz),
            Some(sync_hz),
        ];
        self.watch.update(now_ms, counts, expected);
        if clocks::CLOCK_LOST.load(Ordering::Relaxed) {
            self.watch.clock_lost();
        }
        let faults = self.watch.faults();
        TIMING_FAULT.store(!faults.is_empty(), Ordering::Relaxed);
        let drive_unsafe = faults.contains(TimingFaults::CLOCK_LOST)
            || faults.contains(TimingFaults::of(Event::DriveTick));
        if drive_unsafe && !self.drive_taken_off {
            self.drive_taken_off = true;
            // SAFETY: the DAC's CR and holding register; the drive tick is inhibited below
            // (and is not running: that is the fault), the store's pause is not under way.
            let dac = unsafe { &*pac::DAC::ptr() };
            let mid = dither
                .lock(|task| {
                    task.controller.inhibit();
                    task.config.dac_mid_code
                })
                .unwrap_or(2048);
            dither::force_mid(dac, mid);
            defmt::error!("timing fault {}: drive off", faults);
        }
    }

    /// After a flash store: every monitor starts afresh.
    pub fn restart(&mut self) {
        self.watch.restart();
    }

    /// The faults raised now.
    pub fn faults(&self) -> TimingFaults {
        self.watch.faults()
    }
}
