//! The pick-off stream: the conversion of the pick-off at every drive tick (ADC3 injected,
//! triggered by TIM4 on the F405, 40 kHz), which the firmware's dither drive reads and the
//! readout's dither model (`firmware::signal::output::dither_model`) fits.
//!
//! One conversion per tick, whoever asks first: the firmware's drive, running ahead of the
//! board ([`crate::drive_loop`]), or the board handing the ticks up to its time to the readout
//! (with a prescribed dither nobody drives). The codes are cached by tick until the board has
//! handed them on, so the drive and the readout see the same conversion, as on the board, and
//! the noise draws follow the tick order whoever asks.

use crate::clock::CaptureTimer;
use crate::gyro::Gyro;
use crate::pickoff::Pickoff;
use firmware::sample::AdcCode;
use firmware::signal::output::dither_model::PickoffSample;
use std::collections::VecDeque;

/// Ticks kept converted ahead of the board: 2 s at 40 kHz (the harness keeps a drive at most
/// 1 s ahead).
const MAX_CACHED: usize = 80_000;

/// The stream's timing and the conversions not yet handed to the readout.
#[derive(Clone, Debug)]
pub(super) struct PickoffStream {
    tick_hz: f64,
    /// Drive tick edge to the conversion's sampling instant, s.
    delay_s: f64,
    /// Codes of ticks `first..first + cache.len()`, converted ahead of the board's time (the
    /// drive asked) or not yet handed over.
    cache: VecDeque<AdcCode>,
    first: u64,
    /// The next tick to hand to the readout.
    next: u64,
    /// Handed over since the last drain, in tick order.
    taken: Vec<PickoffSample>,
}

impl PickoffStream {
    /// Ticks at `tick_hz` from t = 0, each sampled `delay_s` after its edge.
    pub(super) fn new(tick_hz: f64, delay_s: f64) -> Self {
        Self {
            tick_hz,
            delay_s,
            cache: VecDeque::new(),
            first: 0,
            next: 0,
            taken: Vec::new(),
        }
    }

    /// The sampling instant of tick `n`, s.
    pub(super) fn instant_s(&self, n: u64) -> f64 {
        n as f64 / self.tick_hz + self.delay_s
    }

    /// The sampling instant of the next tick to hand over, s.
    pub(super) fn next_instant_s(&self) -> f64 {
        self.instant_s(self.next)
    }

    /// The conversion of tick `n`: converted once, in tick order (asking for a later tick
    /// converts the ones before it first), so the noise draws do not depend on who asks. A
    /// tick already dropped (behind both the board and the cache) gets a conversion of its own.
    pub(super) fn code(&mut self, pickoff: &mut Pickoff, gyro: &Gyro, n: u64) -> AdcCode {
        if n < self.first {
            return pickoff.sample_code(gyro, self.instant_s(n));
        }
        while self.first + (self.cache.len() as u64) <= n {
            let k = self.first + self.cache.len() as u64;
            self.cache
                .push_back(pickoff.sample_code(gyro, self.instant_s(k)));
            if self.cache.len() > MAX_CACHED {
                // Nobody hands these over (a drive run without the board stepping).
                self.cache.pop_front();
                self.first += 1;
            }
        }
        self.cache[(n - self.first) as usize]
    }

    /// Hands the next tick's conversion over, stamped by `timer` at its sampling instant (the
    /// output latches' time base: their stamps are their sampling instants too).
    pub(super) fn take_next(&mut self, pickoff: &mut Pickoff, gyro: &Gyro, timer: &CaptureTimer) {
        let n = self.next;
        let code = self.code(pickoff, gyro, n);
        while self.first <= n && self.cache.pop_front().is_some() {
            self.first += 1;
        }
        self.taken.push(PickoffSample {
            timestamp_ticks: timer.ticks_at(self.instant_s(n)),
            code,
        });
        self.next += 1;
    }

    /// The next tick takes no conversion (its trigger stopped): a gap in the stream.
    pub(super) fn skip_next(&mut self) {
        let n = self.next;
        while self.first <= n && self.cache.pop_front().is_some() {
            self.first += 1;
        }
        self.next += 1;
    }

    /// Moves the conversions handed over since the last call into `into` (cleared first).
    pub(super) fn drain(&mut self, into: &mut Vec<PickoffSample>) {
        into.clear();
        into.append(&mut self.taken);
    }
}
