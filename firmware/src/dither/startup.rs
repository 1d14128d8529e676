//! Start-up: finding the resonance from a cold start anywhere in the search range (280-620 Hz
//! on the F405 profile) in a fraction of a second, at any Q.
//!
//! # Listen, sweep, listen, ring up
//! 1. **Listen** (drive off): if the dither already rings (a retry after a fault, a warm
//!    restart), its zero crossings give its frequency and phase at once ([`RingListener`]).
//! 2. **Sweep** (no ring heard within [`StartupConfig::listen_timeout_ticks`]): the drive, at
//!    its limit, sweeps up the search range at [`StartupConfig::sweep_hz_per_s`], then down.
//!    The frequency is a staircase that changes only at the drive's peaks (once per half
//!    cycle, like every drive change). A sweep that is fast against the resonance's bandwidth
//!    (300 Hz/s against (f0/Q)^2 = 0.15 Hz^2) leaves the dither ringing at f0 with an amplitude
//!    of about R / sqrt(rate), R = g * limit the ring-up rate (50-100 arcsec for the drives the
//!    ring-up needs anyway), whatever Q is; a slow sweep would need minutes at Q = 5000. When
//!    a half cycle's peak-to-peak exceeds twice [`StartupConfig::ring_threshold_codes`] the
//!    drive goes off and the controller listens again (1.), now to a ring at f0 itself: the
//!    free ring of a resonator is at its own frequency, whatever drove it.
//! 3. **Ring-up**: the DDS starts at the ring's frequency, 90 degrees ahead of the pick-off,
//!    at the drive limit; the plant gain is measured over the first half cycles, then the
//!    amplitude and frequency loops run (`super::amplitude`, `super::frequency`) until the
//!    amplitude is within [`StartupConfig::lock_tolerance`] of the setpoint and the phase
//!    error within [`StartupConfig::lock_phase_error`] for
//!    [`StartupConfig::lock_half_cycles`]: locked.
//!
//! The ring is timed over [`StartupConfig::ring_half_periods`] half periods (3 periods, 8 ms
//! at 389 Hz), crossings interpolated between samples: with a 12-bit pick-off and a ring of 100
//! codes the frequency is good to ~0.1 Hz, well inside the frequency loop's pull-in.

use crate::units::Phase;

/// The start-up's settings (immutable).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StartupConfig {
    /// The search range as DDS steps (Q32 turns per tick).
    pub search_steps: (Phase, Phase),
    /// The sweep rate, Hz/s (informative; [`Self::sweep_step_per_tick`] is what runs).
    pub sweep_hz_per_s: f32,
    /// The sweep rate as a DDS-step increment per tick (Q32 turns per tick per tick).
    pub sweep_step_per_tick: u32,
    /// A ring is heard above this amplitude (half the peak-to-peak), codes.
    pub ring_threshold_codes: u16,
    /// Half periods timed before the ring-up starts.
    pub ring_half_periods: u8,
    /// Listening without a ring for this long starts (or continues) the sweep, ticks.
    pub listen_timeout_ticks: u32,
    /// Locked when the amplitude is within this fraction of the setpoint...
    pub lock_tolerance: f32,
    /// ...and the phase error within this, Q32 turns...
    pub lock_phase_error: Phase,
    /// ...for this many half cycles in a row.
    pub lock_half_cycles: u16,
    /// The power-up self-test's sweep drive, DAC codes in Q16 (`super::self_test`).
    pub self_test_drive_q16: u32,
}

impl StartupConfig {
    /// The start-up for a search range of `search_hz` at tick rate `tick_hz`, with a drive
    /// limited to `drive_limit_codes`.
    pub fn new(search_hz: (f64, f64), tick_hz: f64, drive_limit_codes: f32) -> Self {
        use super::dds::hz_to_step;
        let sweep_hz_per_s = 300.0;
        let per_tick = sweep_hz_per_s / tick_hz / tick_hz * crate::units::Q32_PER_FRINGE;
        Self {
            search_steps: (
                hz_to_step(search_hz.0, tick_hz),
                hz_to_step(search_hz.1, tick_hz),
            ),
            sweep_hz_per_s: sweep_hz_per_s as f32,
            sweep_step_per_tick: per_tick as u32,
            ring_threshold_codes: 20,
            ring_half_periods: 6,
            // A ring at the lowest frequency is timed within (6 + 1) / 2 = 3.5 periods; one
            // more period of margin.
            listen_timeout_ticks: (4.5 * tick_hz / search_hz.0) as u32 + 1,
            lock_tolerance: 0.002,
            lock_phase_error: Phase::from_bits(1 << 26), // 1/64 turn, 0.1 rad
            lock_half_cycles: 256,
            self_test_drive_q16: (drive_limit_codes
                * super::self_test::SELF_TEST_DRIVE_FRACTION
                * 65_536.0) as u32,
        }
    }
}

/// A ring timed by the [`RingListener`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ring {
    /// Its period, ticks.
    pub period_ticks: f32,
    /// Its last zero crossing, ticks after the listener's origin (fractional: interpolated).
    pub last_crossing: f32,
    /// That crossing was rising (the pick-off going up through its zero).
    pub rising: bool,
}

impl Ring {
    /// The DDS step of the ring's frequency.
    pub fn step(&self) -> Phase {
        let bits = crate::units::Q32_PER_FRINGE / self.period_ticks as f64;
        Phase::from_bits(bits.clamp(0.0, 2_147_483_648.0) as u32)
    }
}

/// Zero crossings of the pick-off with hysteresis, timed to a fraction of a tick; a run of
/// half periods whose longest exceeds 1.5 times its shortest is not a ring and is timed again.
#[derive(Clone, Copy, Debug, Default)]
pub struct RingListener {
    origin: u32,
    center: i32,
    hysteresis: i32,
    side: i8,
    previous: Option<i32>,
    candidate: Option<f32>,
    first: f32,
    last: f32,
    crossings: u8,
    shortest: f32,
    longest: f32,
}

impl RingListener {
    /// Starts listening at tick `origin` around the pick-off zero `center` (centred codes),
    /// with a hysteresis of `hysteresis` codes on each side.
    pub fn new(origin: u32, center: i32, hysteresis: i32) -> Self {
        Self {
            origin,
            center,
            hysteresis,
            ..Self::default()
        }
    }

    /// Ticks since the start.
    pub fn elapsed(&self, tick: u32) -> u32 {
        tick.wrapping_sub(self.origin)
    }

    /// One sample `x` (centred codes) at `tick`; the ring once `half_periods` half periods have
    /// been timed.
    #[inline]
    pub fn push(&mut self, tick: u32, x: i32, half_periods: u8) -> Option<Ring> {
        let t = self.elapsed(tick) as f32;
        if let Some(p) = self.previous {
            let (below, above) = ((p < self.center) as i8, (x >= self.center) as i8);
            if below + above == 2 || (p >= self.center && x < self.center) {
                // The zero lies between p and x: the candidate crossing, confirmed by the
                // hysteresis below.
                let fraction = (self.center - p) as f32 / (x - p) as f32;
                self.candidate = Some(t - 1.0 + fraction);
            }
        }
        self.previous = Some(x);
        let side = if x >= self.center + self.hysteresis {
            1
        } else if x <= self.center - self.hysteresis {
            -1
        } else {
            return None;
        };
        let crossed = self.side != 0 && side != self.side;
        self.side = side;
        let at = self.candidate.take()?;
        if !crossed {
            return None;
        }
        let interval = at - self.last;
        if self.crossings == 0 {
            self.first = at;
            self.shortest = f32::MAX;
            self.longest = 0.0;
        } else {
            self.shortest = self.shortest.min(interval);
            self.longest = self.longest.max(interval);
            if self.longest > 1.5 * self.shortest {
                // Not one sine (noise, a beat): time again from this crossing.
                self.crossings = 0;
                self.first = at;
                self.shortest = f32::MAX;
                self.longest = 0.0;
            }
        }
        self.last = at;
        self.crossings = self.crossings.saturating_add(1);
        if self.crossings <= half_periods {
            return None;
        }
        Some(Ring {
            period_ticks: 2.0 * (self.last - self.first) / half_periods as f32,
            last_crossing: self.last,
            rising: side > 0,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// A decaying ring at `hz` through the 12-bit ADC, listened to until timed.
    fn listen(hz: f64, amp: f64, phase: f64, noise_seed: u64) -> (Ring, u32) {
        let mut rng = crate::test_rng::XorShift(noise_seed);
        let mut l = RingListener::new(500, 0, 10);
        for k in 500u32..5000 {
            let t = (k - 500) as f64 / 40_000.0;
            let v = amp * (-t / 0.8).exp() * (TAU * hz * t + phase).sin() + rng.gauss();
            if let Some(r) = l.push(k, v.round() as i32, 6) {
                return (r, k);
            }
        }
        panic!("no ring");
    }

    #[test]
    fn times_a_ring_to_a_fraction_of_a_percent_at_both_ends_of_the_range() {
        for (hz, amp) in [(280.0, 40.0), (389.0, 100.0), (620.0, 40.0)] {
            let (ring, at) = listen(hz, amp, 1.0, 5);
            let measured = 40_000.0 / ring.period_ticks as f64;
            assert!((measured / hz - 1.0).abs() < 2e-3, "{hz}: {measured}");
            // The last crossing is a true zero of the sine: phase 1 + 2 pi hz t = k pi.
            let t = ring.last_crossing as f64 / 40_000.0;
            let cycles = (1.0 + TAU * hz * t) / std::f64::consts::PI;
            assert!((cycles - cycles.round()).abs() < 0.01, "{cycles}");
            let rising = (cycles.round() as i64) % 2 == 0;
            assert_eq!(ring.rising, rising);
            assert!(at < 500 + (4.0 * 40_000.0 / hz) as u32);
        }
    }

    #[test]
    fn noise_below_the_hysteresis_is_no_ring() {
        let mut l = RingListener::new(0, 0, 10);
        let mut rng = crate::test_rng::XorShift(9);
        for k in 0..40_000u32 {
            assert_eq!(l.push(k, (3.0 * rng.gauss()) as i32, 6), None);
        }
    }

    #[test]
    fn sweep_rate_in_steps() {
        let c = StartupConfig::new((280.0, 620.0), 40_000.0, 1798.0);
        // 300 Hz/s for one second of ticks moves the step by 300 Hz.
        let hz = c.sweep_step_per_tick as f64 * 40_000.0 / crate::units::Q32_PER_TURN * 40_000.0;
        assert!((hz - 300.0).abs() < 0.5, "{hz}");
        assert_eq!(c.listen_timeout_ticks, 643);
    }
}
